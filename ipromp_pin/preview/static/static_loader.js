(function () {
  const commands = JSON.parse(document.getElementById("ipromp-scene").textContent);
  for (const c of commands) {
    const bin = atob(c);
    const bytes = new Uint8Array(bin.length);
    for (let i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
    viewer.handle_command_bytearray(bytes);
  }
  window.iprompReady = commands.length;
})();
