"""The one warm-up compiles every kernel signature that a run uses, so that the run after the background
compile compiles nothing (a kernel called with an F-ordered or strided array has a second signature,
which numba compiles on the spot: 15 s of CPU in a "warm" run before this was tested)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

SCRIPT = """
import json, sys
from ipromp_pin.promp import compiled, warmup
from ipromp_pin.human import kernels as human, warmup as human_warmup
warmup.compile_kernels()
human_warmup.compile_kernels()
modules = {name: compiled.numba_kernels(name) for name in ("inference", "human")}

def signatures():
    out = {}
    for set_name, module in modules.items():
        for name in dir(module):
            kernel = getattr(module, name)
            if hasattr(kernel, "signatures"):
                out[f"{set_name}.{name}"] = [str(s) for s in kernel.signatures]
    return out

before = signatures()
from ipromp_pin.app import main
code = main(["run", "pipelines/baxter_handover.toml", "--out", sys.argv[1], "--no-preview", "--no-rosbag"])
after = signatures()
print(json.dumps({"code": code, "new": {k: v for k, v in after.items() if v != before.get(k, [])}}))
"""


def test_a_run_after_the_warm_up_compiles_no_kernel(tmp_path):
    env = {**os.environ, "IPROMP_PIN_KERNELS": "numba", "IPROMP_PIN_CACHE_DIR": str(tmp_path / "cache")}
    done = subprocess.run(
        [sys.executable, "-c", SCRIPT, str(tmp_path / "out")],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert result["code"] == 0
    new = result["new"]
    assert not new, f"kernels compiled again by the run (signatures the warm-up lacks): {new}"
