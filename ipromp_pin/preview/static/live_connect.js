viewer.connect((location.protocol === "https:" ? "wss://" : "ws://") + location.host + "/ws");
