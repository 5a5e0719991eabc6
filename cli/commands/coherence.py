"""`strokekit coherence OUT_DIR`: temporal coherence metrics (BRIEF 3) of a rendered sequence."""

from __future__ import annotations

import click
import orjson
from rich.console import Console
from rich.table import Table

from strokekit.errors import InputError
from strokekit.metrics.coherence import folder_metrics

from ..common import FiniteFloatRange
from .render_options import occlusion_from

_COLUMNS = [("frame", "pair", "{:d}"), ("M1", "M1 ids", "{:.3f}"), ("M2", "M2 pop", "{:.4f}"),
            ("M4_median", "M4 med px", "{:.2f}"), ("M4_p95", "M4 p95 px", "{:.2f}"), ("M4_max", "M4 max px", "{:.2f}"),
            ("M5", "M5 oct", "{:.3f}"), ("M5_raw", "M5 raw", "{:.3f}"), ("M7_median", "M7 med px", "{:.2f}"),
            ("M7_max", "M7 max px", "{:.2f}")]


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
def command(out_dir: str, as_json: bool, radius: float, min_dot: float, pattern: str, occlusion_range: str | None):
    """Per frame pair and overall: M1 id persistence, M2 popping, M4 sliding (median/p95/max px),
    M5 flatness (octaves, with self-similar levels and raw u), M7 end growth, from the
    frame JSON files of OUT_DIR (README: what each metric measures)."""
    levels = occlusion_from({"occlusion_range": occlusion_range}) if occlusion_range is not None else None
    pairs, total = folder_metrics(out_dir, pattern, occlusion=levels, radius_px=radius, min_tangent_dot=min_dot)
    for p in pairs:
        if p.frame - p.prev_frame != 1:
            click.echo(f"strokekit: warning: frame {p.frame} is compared with frame {p.prev_frame} "
                       f"(frames in between are missing)", err=True)
    if pairs and total["total_px"] == 0:
        where = f" at occlusion levels {occlusion_range}" if occlusion_range is not None else ""
        raise InputError(f"its {len(pairs) + 1} frames hold no strokes{where}: nothing to measure", out_dir)
    rows = [p.summary() for p in pairs]
    if as_json:
        click.echo(orjson.dumps({"pairs": rows, "overall": total}, option=orjson.OPT_INDENT_2).decode())
        return

    t = Table(title=f"coherence of {out_dir} ({len(pairs)} frame pairs)")
    for _, head, _ in _COLUMNS:
        t.add_column(head, justify="right")
    for r in rows:
        t.add_row(*[f.format(r[k]) for k, _, f in _COLUMNS])
    t.add_section()
    o = {**total, "frame": -1, "M2": total["M2_median"]}
    t.add_row("all", *[f.format(o[k]) for k, _, f in _COLUMNS[1:]])
    Console(width=max(Console().width, 132)).print(t)
    click.echo(f"overall: M1 {total['M1']:.3f}  M2 median {total['M2_median']:.4f} (mean {total['M2_mean']:.4f})  "
               f"M4 median {total['M4_median']:.2f} p95 {total['M4_p95']:.2f} max {total['M4_max']:.2f} px  "
               f"M5 {total['M5']:.3f} oct (raw {total['M5_raw']:.3f})  M7 median {total['M7_median']:.2f} px")
