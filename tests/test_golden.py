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
