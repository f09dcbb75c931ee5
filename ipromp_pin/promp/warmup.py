"""The one warm-up: compile the package's kernels into numba's on-disk cache,
``python -m ipromp_pin.promp.warmup [--also=MODULE ...]``.

Runs the compiled inference kernels once on a small synthetic problem (fit with cross-validation,
predict, stream a few samples), which compiles every kernel with the signatures the package uses,
then every other registered kernel set's ``compile_kernels()`` named by ``--also`` (the human
checks': ``--also=ipromp_pin.human.warmup``), and checks that the cache now holds them.
:func:`ipromp_pin.promp.compiled.start_background_compile` starts it in the background with every
registered set (with ``--lock``: the lock file it removes when done, and ``compile.failed`` beside it
when the compile fails, so that it is not retried on every run).
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
import time
import traceback
from pathlib import Path

import numpy as np

STREAMING_KERNELS = ("stream_sample", "sherman_morrison", "stream_group", "add_sample", "basis_rows")


def compile_kernels() -> float:
    """Compile (or load) every kernel through the real code paths; returns the time taken in [s]."""
    from ..readers.synthetic import make_synthetic_dataset
    from .compiled import FIT_PREDICT_KERNELS, compiled_kernels_cached, use_kernels
    from .estimator import IProMP

    t0 = time.perf_counter()
    with use_kernels("numba"):
        data = make_synthetic_dataset(n_tasks=2, n_demos=5, seed=0)
        demos = data.all_demos()
        model = IProMP(observe=["orientation", "emg"], n_basis=9, n_alpha=20).fit(demos[1:])
        observation = demos[0].head(0.3, groups=model.observe)
        prediction = model.predict(observation)
        assert not isinstance(prediction, list)  # one observation, one prediction
        # the hand-over estimates' read-out update (a model fitted with the robot's kinematics): one
        # call with the shapes it gets, (3, J) read-out of the last phase's joint angles
        weights = prediction.robot_weights
        if weights is not None:
            joints = prediction.q_mean.shape[1]
            weights.readout_update(weights.phi[-1], np.eye(3, joints), np.zeros(3), np.eye(3) * 1e-2)
        stream = model.stream()
        for i, t in enumerate(observation.t[:6]):
            stream.update(float(t), {g: observation.groups[g][i] for g in observation.groups})
    if not compiled_kernels_cached(FIT_PREDICT_KERNELS + STREAMING_KERNELS):
        raise RuntimeError("the kernels ran but numba's cache does not hold them (is its folder writable?)")
    return time.perf_counter() - t0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lock", type=Path, help="lock file to remove when done")
    parser.add_argument(
        "--also", action="append", default=[], help="module whose compile_kernels() to run too (repeatable)"
    )
    args = parser.parse_args(argv)
    if hasattr(os, "nice"):
        os.nice(10)  # a background job: the user's own work goes first
    code = 0
    try:
        print(f"compiled the inference kernels in {compile_kernels():.1f} s", flush=True)
        for module in args.also:
            seconds = importlib.import_module(module).compile_kernels()
            print(f"compiled the kernels of {module} in {seconds:.1f} s", flush=True)
    except Exception:  # recorded for the parent, which then stops retrying for a day
        traceback.print_exc()
        code = 1
        if args.lock is not None:
            try:
                args.lock.with_name("compile.failed").write_text(traceback.format_exc())
            except OSError:
                pass
    finally:
        if args.lock is not None:
            args.lock.unlink(missing_ok=True)
    return code


if __name__ == "__main__":
    sys.exit(main())
