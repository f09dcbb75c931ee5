"""``ipromp-pin synth --csv`` writes the built-in synthetic demos as native CSV files that read back."""

from __future__ import annotations

import numpy as np

from ipromp_pin.app import main
from ipromp_pin.readers import detect_format, load_dataset
from ipromp_pin.readers.synthetic import make_synthetic_dataset


def test_synth_csv_writes_native_csv_that_reads_back(tmp_path, capsys):
    out = tmp_path / "data"
    assert main(["synth", str(out), "--csv", "--tasks", "2", "--demos", "3", "--seed", "4"]) == 0
    assert "(.csv files)" in capsys.readouterr().out
    files = sorted(p.relative_to(out).as_posix() for p in out.rglob("*"))
    assert files == ["rod", "rod/rod_000.csv", "rod/rod_001.csv", "rod/rod_002.csv"] + [
        "wrench", "wrench/wrench_000.csv", "wrench/wrench_001.csv", "wrench/wrench_002.csv"
    ]  # fmt: skip
    assert (out / "rod" / "rod_000.csv").read_text().startswith("t,orientation.qw,")
    assert detect_format(out / "rod") == "native"
    got = load_dataset(out)
    want = make_synthetic_dataset(n_tasks=2, n_demos=3, seed=4)
    for task in want.tasks:
        for a, b in zip(got.demos[task], want.demos[task], strict=True):
            assert a.name == b.name and set(a.groups) == set(b.groups)
            np.testing.assert_allclose(a.t, b.t, rtol=1e-11, atol=1e-12)
            for g in b.groups:
                np.testing.assert_allclose(a.groups[g], b.groups[g], rtol=1e-11, atol=1e-12)
            np.testing.assert_allclose(a.extras["hand_position"], b.extras["hand_position"], rtol=1e-11)
