"""Importing the timing code does not load matplotlib.pyplot (toppra imports it for plots the package
never draws); pyplot still works for whoever uses it, through toppra's name or a later import."""

from __future__ import annotations

import subprocess
import sys

CODE = """
import sys
import ipromp_pin.motion.timing
import toppra.algorithm.algorithm as algorithm
assert "matplotlib.figure" not in sys.modules, "pyplot was loaded"
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
fig = plt.figure()
assert type(fig).__name__ == "Figure" and "matplotlib.figure" in sys.modules
assert algorithm.plt.figure is plt.figure  # toppra's stand-in answers from the real module
assert sys.modules["matplotlib.pyplot"].__file__.endswith("pyplot.py")
print("ok")
"""


def test_toppra_does_not_load_pyplot_and_pyplot_still_works():
    out = subprocess.run([sys.executable, "-c", CODE], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"
