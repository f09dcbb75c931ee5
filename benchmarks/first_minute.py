"""Benchmark: the first minute of a new user, ``ipromp-pin run pipelines/baxter_handover.toml``.

Runs the README's first command (the ``ipromp-pin run`` part, as ``python -m ipromp_pin.app run``,
preview included) in fresh processes and measures, per run, the wall time to the command's exit and
the CPU time of the command's process (user + system):

* **cold**: as on a fresh clone with the environment installed (the README's first command after
  ``pip install -e .``): the committed tree is cloned into a temporary folder (no numba cache, no
  bytecode of the package's own modules) and run from there with an empty ipromp_pin cache
  (``IPROMP_PIN_CACHE_DIR``). The inference kernels then run in their numpy version while a detached
  background process compiles them; the benchmark waits for that compile to finish (and reports how
  long it took) before the next run;
* **warm**: the next run in the same clone (same caches).

With ``--baseline REV`` it also measures another commit the same way (fresh clones of ``REV``, empty
numba cache): e.g. the version before the fast first minute, whose first run compiles the kernels
and whose every preview decimates the meshes again. Uncommitted changes are not measured: commit
first.

    python benchmarks/first_minute.py [--repeats 3] [--baseline REV] [--json FILE]

``--smoke``: one run of this checkout in place (no clone), with a small model trained first and
no preview: seconds, what the test suite runs so that the script cannot silently rot.

Prints the medians (and every run) and the machine's load average, which on a shared machine says
how much the wall times are stretched (the CPU times much less so).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def clone(folder: Path, rev: str | None = None) -> Path:
    """A fresh clone of the committed tree of this checkout (at ``rev`` when given)."""
    subprocess.run(["git", "clone", "-q", "--no-hardlinks", str(ROOT), str(folder)], check=True)
    if rev is not None:
        subprocess.run(["git", "-C", str(folder), "checkout", "-q", rev], check=True)
    return folder


def run_once(
    env: dict[str, str], tree: Path, out: Path, extra: tuple[str, ...] = ()
) -> dict[str, float | str]:
    """One ``ipromp-pin run`` of ``tree`` in a new process (``extra``: more arguments): wall and CPU
    time in [s], and its output."""
    command = [sys.executable, "-m", "ipromp_pin.app", "run", "pipelines/baxter_handover.toml", *extra]
    env = {**env, "PYTHONPATH": str(tree)}
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(
        [*command, "--out", str(out)], env=env, cwd=tree, capture_output=True, text=True, check=False
    )
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise SystemExit(f"run failed ({proc.returncode}):\n{proc.stdout}\n{proc.stderr}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return {"wall_s": wall, "cpu_s": cpu, "output": proc.stdout + proc.stderr}


def wait_for_background_compile(cache: Path, timeout_s: float = 600.0) -> float | None:
    """Seconds the detached kernel compile reported (None if none ran), after waiting for it."""
    lock = cache / "kernels" / "compile.lock"
    log = cache / "kernels" / "compile.log"
    deadline = time.monotonic() + timeout_s
    while lock.exists() and time.monotonic() < deadline:
        time.sleep(0.5)
    if not log.exists():
        return None
    for line in log.read_text().splitlines():
        if line.startswith("compiled the inference kernels in "):
            return float(line.split(" in ")[1].split(" s")[0])
    raise SystemExit(f"the background compile failed:\n{log.read_text()}")


def median(rows: list[dict], key: str) -> float:
    return statistics.median(float(r[key]) for r in rows)


def smoke(tmp: Path) -> dict[str, list]:
    """``--smoke``: one run of this checkout in place (no clone) with an empty cache, the numpy kernels
    (no background compile), a small model trained here (no training in the run), no preview."""
    from threadpoolctl import threadpool_limits

    from ipromp_pin import IProMP
    from ipromp_pin.readers.synthetic import make_synthetic_dataset

    model = tmp / "small.npz"
    with threadpool_limits(1):
        ds = make_synthetic_dataset(n_tasks=3, n_demos=4, seed=0)
        IProMP(noise=10.0, head=False, handover=False, coupling="all", novelty_alpha=None).fit(ds).save(model)
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "PYTHONPATH")}
    env.update(IPROMP_PIN_CACHE_DIR=str(tmp / "cache"), IPROMP_PIN_KERNELS="numpy")
    extra = ("--model", str(model), "--no-preview")
    cold = run_once(env, ROOT, tmp / "smoke", extra)
    print(f"smoke: {cold['wall_s']:.1f} s wall, {cold['cpu_s']:.1f} s CPU", flush=True)
    return {"cold": [cold], "warm": [], "compile_s": []}


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--repeats", type=int, default=3, help="cold runs and warm runs each (default 3)")
    parser.add_argument(
        "--baseline", metavar="REV", help="also measure this commit (e.g. the version before)"
    )
    parser.add_argument("--json", type=Path, help="write the results here")
    parser.add_argument("--smoke", action="store_true", help="one run in place, small model: seconds")
    args = parser.parse_args()

    drop = ("IPROMP_PIN_KERNELS", "NUMBA_CACHE_DIR", "IPROMP_PIN_CACHE_DIR", "PYTHONPATH")
    base_env = {k: v for k, v in os.environ.items() if k not in drop}
    load0 = os.getloadavg()
    results: dict[str, list[dict]] = {"cold": [], "warm": [], "compile_s": []}
    with tempfile.TemporaryDirectory(ignore_cleanup_errors=True) as tmp:
        tmp = Path(tmp)
        if args.smoke:
            results = smoke(tmp)
            args.repeats, args.baseline = 0, None
        for i in range(args.repeats):
            tree = clone(tmp / f"clone{i}")
            env = {**base_env, "IPROMP_PIN_CACHE_DIR": str(tmp / f"c{i}")}
            cold = run_once(env, tree, tmp / f"cold{i}")
            results["compile_s"].append(wait_for_background_compile(tmp / f"c{i}"))
            results["cold"].append(cold)
            print(f"cold {i + 1}: {cold['wall_s']:.1f} s wall, {cold['cpu_s']:.1f} s CPU", flush=True)
            warm = run_once(env, tree, tmp / f"warm{i}")
            results["warm"].append(warm)
            print(f"warm {i + 1}: {warm['wall_s']:.1f} s wall, {warm['cpu_s']:.1f} s CPU", flush=True)
        if args.baseline:
            results["baseline_cold"], results["baseline_warm"] = [], []
            for i in range(args.repeats):
                tree = clone(tmp / f"bclone{i}", args.baseline)
                env = {**base_env, "IPROMP_PIN_CACHE_DIR": str(tmp / f"bc{i}")}
                cold = run_once(env, tree, tmp / f"bcold{i}")
                results["baseline_cold"].append(cold)
                warm = run_once(env, tree, tmp / f"bwarm{i}")
                results["baseline_warm"].append(warm)
                print(
                    f"baseline {i + 1}: cold {cold['wall_s']:.1f} s wall ({cold['cpu_s']:.1f} s CPU), "
                    f"warm {warm['wall_s']:.1f} s wall ({warm['cpu_s']:.1f} s CPU)",
                    flush=True,
                )
    load1 = os.getloadavg()
    print(
        f"\nmachine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, Python "
        f"{platform.python_version()}; load average {load0[0]:.1f} at the start, {load1[0]:.1f} at the end"
    )
    summary = {}
    for kind in [k for k in ("cold", "warm", "baseline_cold", "baseline_warm") if results.get(k)]:
        rows = results[kind]
        summary[kind] = {"wall_s": median(rows, "wall_s"), "cpu_s": median(rows, "cpu_s")}
        print(
            f"{kind:<14} median {summary[kind]['wall_s']:5.1f} s wall, {summary[kind]['cpu_s']:5.1f} s CPU "
            f"(walls: {', '.join(format(r['wall_s'], '.1f') for r in rows)})"
        )
    compiles = [c for c in results["compile_s"] if c is not None]
    if compiles:
        print(f"background compile (after each cold run): median {statistics.median(compiles):.1f} s")
    print("targets: cold <= 10 s, warm <= 3 s (wall, to the command's exit)")
    if args.json:
        doc = {
            "summary": summary,
            "background_compile_s": compiles,
            "runs": {
                k: [{kk: vv for kk, vv in r.items() if kk != "output"} for r in v]
                for k, v in results.items()
                if k != "compile_s"
            },
            "load_average": [load0[0], load1[0]],
            "cores": os.cpu_count(),
            "python": platform.python_version(),
            "command": " ".join(["python", "benchmarks/first_minute.py", *sys.argv[1:]]),
            "commit": subprocess.run(
                ["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True, text=True
            ).stdout.strip(),
            "baseline": args.baseline,
        }
        args.json.write_text(json.dumps(doc, indent=1))


if __name__ == "__main__":
    main()
