"""`strokekit coherence OUT_DIR`: temporal coherence metrics (BRIEF 3) of a rendered sequence."""

from __future__ import annotations

import click

from strokekit.errors import InputError

from ..common import FiniteFloatRange
from .render_options import occlusion_from

_COLUMNS = [("frame", "pair", "{:d}"), ("M1", "M1 ids", "{:.3f}"), ("M2", "M2 pop", "{:.4f}"),
            ("M4_median", "M4 med px", "{:.2f}"), ("M4_p95", "M4 p95 px", "{:.2f}"), ("M4_max", "M4 max px", "{:.2f}"),
            ("M5", "M5 oct", "{:.3f}"), ("M5_raw", "M5 raw", "{:.3f}"), ("M7_median", "M7 med px", "{:.2f}"),
            ("M7_max", "M7 max px", "{:.2f}"), ("M8", "M8 ends/kpx", "{:.2f}")]
_FRESH_COLUMNS = [("M8_fresh", "fresh", "{:.2f}"), ("M8_ratio", "x fresh", "{:.2f}")]


@click.command("coherence", short_help="Temporal coherence metrics of a rendered sequence.")
@click.argument("out_dir", type=click.Path())
@click.option("--json", "as_json", is_flag=True, help="Print JSON (per pair and overall) instead of a table.")
@click.option("--radius", type=FiniteFloatRange(min=0, min_open=True), default=6.0, show_default=True,
              help="Match radius, px.")
@click.option("--min-dot", type=FiniteFloatRange(0, 1), default=0.65, show_default=True,
              help="Minimum |t.t'| of a match (0 to 1).")
@click.option("--pattern", default="frame_{frame:04d}", show_default=True,
              help="File name pattern of the frames (as given to render --pattern).")
@click.option("--occlusion", "occlusion_range", default=None,
              help="Only the strokes of occlusion levels A-B (a --hidden render: 1- measures the hidden lines).")
@click.option("--fresh", "fresh_dir", type=click.Path(), default=None,
              help="The same frames drawn afresh (rendered with --no-coherence --strokes brush): M8, the path "
                   "ends against theirs.")
@click.option("--scene", "scene_path", type=click.Path(), default=None,
              help="The moving scene the frames were rendered from: its deforming objects' points move with their "
                   "mesh too (the frame JSON alone moves the rigid objects' points).")
@click.option("--animation", default=None, help="With --scene: the animation the frames were rendered with "
              "[the first].")
def command(out_dir: str, as_json: bool, radius: float, min_dot: float, pattern: str, occlusion_range: str | None,
            fresh_dir: str | None, scene_path: str | None, animation: str | None):
    """Per frame pair and overall: M1 id persistence, M2 popping, M4 sliding (median/p95/max px),
    M5 flatness (octaves, with self-similar levels and raw u), M7 end growth, M8 path ends per
    1000 px (with --fresh: beside those of the same frames drawn afresh, and the ratio; overall:
    medians over the second half of the frames), from the frame JSON files of OUT_DIR
    (docs/coherence.md: what each metric measures)."""
    import orjson
    from rich.console import Console
    from rich.table import Table

    from strokekit.metrics.coherence import posed_frames, read_frames, sequence_metrics, wholeness
    from strokekit.scene.load import load_scene

    levels = occlusion_from({"occlusion_range": occlusion_range}) if occlusion_range is not None else None
    frames = read_frames(out_dir, pattern, occlusion=levels)
    if scene_path is not None:
        frames = posed_frames(frames, load_scene(scene_path), animation, out_dir)
    fresh = read_frames(fresh_dir, pattern, occlusion=levels, at_least=1) if fresh_dir is not None else None
    if fresh is not None:
        _same_strokes(out_dir, fresh_dir, pattern)
    pairs, total = sequence_metrics(frames, radius_px=radius, min_tangent_dot=min_dot)
    for p in pairs:
        if p.frame - p.prev_frame != 1:
            click.echo(f"strokekit: warning: frame {p.frame} is compared with frame {p.prev_frame} "
                       f"(frames in between are missing)", err=True)
    if pairs and total["total_px"] == 0:
        where = f" at occlusion levels {occlusion_range}" if occlusion_range is not None else ""
        raise InputError(f"its {len(pairs) + 1} frames hold no strokes{where}: nothing to measure", out_dir)
    try:
        per_frame, whole = wholeness(frames, fresh)
    except InputError as e:
        raise InputError(str(e), fresh_dir) from None
    if fresh is not None:
        late = per_frame[len(per_frame) // 2:]
        have = {int(f.frame) for f in fresh}
        missing = [r.frame for r in late if r.frame not in have]
        if len(missing) == len(late):
            raise InputError(f"holds none of the frames {late[0].frame}-{late[-1].frame} (the second half of "
                             f"{out_dir}) to compare with", fresh_dir)
        if missing:
            click.echo(f"strokekit: warning: {len(missing)} of the frames {late[0].frame}-{late[-1].frame} are not "
                       f"in {fresh_dir}: M8's ratio is the median over the other {len(late) - len(missing)}",
                       err=True)
    m8 = {r.frame: r for r in per_frame}
    rows = []
    for p in pairs:
        r = m8[p.frame]
        rows.append({**p.summary(), "M8": r.ends_per_kpx,
                     **({"M8_fresh": r.fresh_ends_per_kpx, "M8_ratio": r.ratio} if fresh is not None else {})})
    if fresh is None:
        whole = {k: v for k, v in whole.items() if k in ("M8", "M8_late_first")}
    total = {**total, **whole}
    if as_json:
        click.echo(orjson.dumps({"pairs": rows, "overall": total},
                                option=orjson.OPT_INDENT_2 | orjson.OPT_SERIALIZE_NUMPY).decode())
        return

    columns = _COLUMNS + (_FRESH_COLUMNS if fresh is not None else [])
    t = Table(title=f"coherence of {out_dir} ({len(pairs)} frame pairs)")
    for _, head, _ in columns:
        t.add_column(head, justify="right")
    for r in rows:
        t.add_row(*[f.format(r[k]) for k, _, f in columns])
    t.add_section()
    o = {**total, "frame": -1, "M2": total["M2_median"]}
    t.add_row("all", *[f.format(o[k]) if not k.startswith("M8") else "" for k, _, f in columns[1:]])
    t.add_row("late", *[f.format(o[k]) if k.startswith("M8") else "" for k, _, f in columns[1:]])
    Console(width=max(Console().width, 150)).print(t)
    click.echo(f"overall: M1 {total['M1']:.3f}  M2 median {total['M2_median']:.4f} (mean {total['M2_mean']:.4f})  "
               f"M4 median {total['M4_median']:.2f} p95 {total['M4_p95']:.2f} max {total['M4_max']:.2f} px  "
               f"M5 {total['M5']:.3f} oct (raw {total['M5_raw']:.3f})  M7 median {total['M7_median']:.2f} px")
    late = f"frames {whole['M8_late_first']}-{per_frame[-1].frame}"
    line = f"M8 wholeness ({late}, median): {whole['M8']:.2f} ends per 1000 px"
    if fresh is not None:
        line += (f", drawn afresh {whole['M8_fresh']:.2f}: {whole['M8_ratio']:.2f} x fresh "
                 f"(over {whole['M8_frames']} frames)")
    click.echo(line)


def _same_strokes(out_dir: str, fresh_dir: str, pattern: str) -> None:
    """The fresh frames must be the strokes of OUT_DIR drawn afresh: brush paths against brush
    paths (`--no-coherence` alone renders lines)."""
    from strokekit.metrics.coherence import holds_brush_paths

    tracked, fresh = holds_brush_paths(out_dir, pattern), holds_brush_paths(fresh_dir, pattern)
    if tracked is None or fresh is None or tracked == fresh:
        return
    name = {True: "brush paths", False: "lines"}
    redo = "render them with --no-coherence --strokes brush" if tracked else "render them with --no-coherence"
    raise InputError(f"holds {name[fresh]} and {out_dir} {name[tracked]}: M8 compares the same strokes drawn "
                     f"afresh ({redo})", fresh_dir)
