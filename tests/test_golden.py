"""Golden drawings of the bundled sample: a fresh render must match the reviewed SVGs within 0.05 px
per line kind (ids may be renumbered), checked with `strokekit diff` as a user's CI would."""

from __future__ import annotations


import pytest

from cli.main import main
from helpers import ROOT, SAMPLES

GOLDEN = ROOT / "tests" / "golden" / "still_life"


def test_sample_matches_golden_svgs(tmp_path, capsys):
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as e:
        main(["render", str(SAMPLES / "still_life.glb"), "--camera", str(SAMPLES / "orbit.json"),
              "--frames", "1,12,24", "--no-json", "--out", str(out), "-q"])
    assert e.value.code == 0
    with pytest.raises(SystemExit) as e:
        main(["diff", str(GOLDEN), str(out), "--tol", "0.05", "--png", str(tmp_path / "diff")])
    report = capsys.readouterr().out
    assert e.value.code == 0, report


def test_round_list_is_pythons_round():
    """The JSON writer rounds lengths in numpy (writers.strokes_json.round_list); the bytes must
    stay those of Python's round(), ties and near-ties included."""
    import numpy as np

    from strokekit.writers.strokes_json import round_list

    rng = np.random.default_rng(7)
    for nd in (4, 5, 6):
        x = np.r_[rng.uniform(0, 3000, 20000), rng.uniform(-1, 1, 2000),
                  (rng.integers(0, 10**7, 5000) + 0.5) / 10.0**nd, rng.integers(0, 10**7, 5000) / 10.0**(nd + 1),
                  [0.0, -0.0, 2.675, 1.00005, 0.00015, 1e-9, -1e-9, 1e20, np.inf, -np.inf]]
        got, want = round_list(x, nd), [round(v, nd) for v in x.tolist()]
        assert [repr(v) for v in got] == [repr(v) for v in want]
