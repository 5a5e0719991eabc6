"""Golden drawings of the bundled sample: a fresh render must match the reviewed SVGs within 0.05 px
per line kind (ids may be renumbered), checked with `strokekit diff` as a user's CI would."""

from __future__ import annotations

import pytest
from helpers import ROOT, SAMPLES

from strokekit_cli.main import main

GOLDEN = ROOT / "tests" / "golden" / "still_life"


def test_sample_matches_golden_svgs(tmp_path, capsys):
    """The golden drawings are the exact lines (--strokes lines: what golden diffs and plotters
    compare; a sequence draws brush paths by default)."""
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as e:
        main(["render", str(SAMPLES / "still_life.glb"), "--camera", str(SAMPLES / "orbit.json"),
              "--frames", "1,12,24", "--strokes", "lines", "--no-json", "--out", str(out), "-q"])
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


def _random_strokes(rng, n_strokes: int):
    """Strokes with the numbers writers trip on: ties at the written decimals, -0.0, tiny
    negatives, constant and varying levels, large and tiny surface values."""
    from dataclasses import replace

    import numpy as np

    from strokekit.model import Strokes

    counts = rng.integers(1, 30, n_strokes)
    n = int(counts.sum())
    pts = rng.normal(0, 10.0 ** rng.integers(0, 5), (n, 2))
    pts[rng.random((n, 2)) < 0.05] = -0.0
    ties = rng.random((n, 2)) < 0.2
    pts[ties] = (rng.integers(-10**6, 10**6, int(ties.sum())) + 0.5) / 100.0
    pts[rng.random((n, 2)) < 0.05] = -1e-7
    surf = rng.normal(0, 10.0 ** rng.integers(-3, 4), (n, 3))
    surf[rng.random((n, 3)) < 0.05] = -0.0
    s = Strokes.build(pts, surf, rng.integers(-1, 10**6, n), np.r_[0, np.cumsum(counts)],
                      rng.integers(0, 8, n_strokes), ids=rng.integers(0, 10**6, n_strokes))
    level = np.full(n_strokes, -0.0) if rng.random() < 0.5 else np.round(rng.normal(0, 3, n_strokes) * 2e6) / 2e6
    return replace(s, level=level, u=np.where(rng.random(n) < 0.1, -0.0, s.u))


def test_writers_fast_paths_write_the_plain_bytes():
    """strokes_json cuts orjson's text of whole arrays at the stroke starts and the SVG writes its
    numbers by integer digit arithmetic: the bytes must stay those of orjson.dumps of the nested
    document and of "%.2f" per number."""
    import numpy as np

    from strokekit.model import Strokes
    from strokekit.style import LineSet, Noise, Style, apply_style
    from strokekit.writers.strokes_json import _strokes_json_nested, strokes_json
    from strokekit.writers.svg import point_strings, stroke_path_data
    from strokekit.writers.text import fixed_point_text

    def nested(s, *args, **kw):
        return _strokes_json_nested(apply_style(s, ()), *args, **kw)

    rng = np.random.default_rng(11)
    noisy = Style(sets=(LineSet("all", thickness=(Noise(amplitude=0.5, wavelength=200.0),)),))
    for trial in range(40):
        s = _random_strokes(rng, int(rng.integers(1, 40)))
        extra = {"tracking": {"matched": 3}} if trial % 2 else None
        assert strokes_json(s, 640, 480, trial, extra=extra) == nested(s, 640, 480, trial, extra=extra)
        styled = apply_style(s, (), noisy)  # widths that vary along the strokes, points added
        assert strokes_json(s, 640, 480, trial, extra=extra, styled=styled) == _strokes_json_nested(
            styled, 640, 480, trial, extra=extra)
        for d in (0, 2, 3):
            want = [" ".join(point_strings(s.points[a:b], d)) for a, b in zip(s.offsets[:-1], s.offsets[1:])]
            assert stroke_path_data(s, d) == want
    # Strided surface / face arrays (views of wider ones), one point per stroke: orjson refuses
    # strided arrays, the nested path never saw one whole.
    from dataclasses import replace

    one = _random_strokes(rng, 6)
    one = Strokes.build(one.points[one.offsets[:-1]], one.surface[one.offsets[:-1]], one.face[one.offsets[:-1]],
                        np.arange(7), one.kind, ids=one.ids)
    strided = replace(one, surface=np.c_[one.surface, one.surface][:, :3],
                      face=np.repeat(one.face, 2)[::2])
    assert not strided.surface.flags.c_contiguous and not strided.face.flags.c_contiguous
    assert strokes_json(strided, 64, 64, 1) == nested(one, 64, 64, 1)
    empty = Strokes.empty()
    assert strokes_json(empty, 8, 8, 1) == nested(empty, 8, 8, 1)
    assert stroke_path_data(empty) == []
    for d in range(0, 8):
        v = np.r_[rng.normal(0, 10.0 ** rng.integers(-3, 14 - d, 4000)), -0.0, 0.0, 0.5 / 10**d, -0.5 / 10**d,
                  (rng.integers(-10**6, 10**6, 2000) + 0.5) / 10.0**d]
        text = fixed_point_text(v, d, np.full(len(v), 32, np.uint8))
        assert text.decode() == "".join(f"%.{d}f " % x for x in (np.round(v, d) + 0.0).tolist())
    assert fixed_point_text(np.array([1.0, np.nan]), 2, np.zeros(2, np.uint8)) is None
