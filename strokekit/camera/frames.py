"""Frame selections like '1-24', '1,3,7-9' (1-based output frame numbers)."""

from __future__ import annotations

from strokekit.errors import UsageError


def parse_frames(spec: str | None, count: int) -> list[int]:
    """Frame numbers (1-based, sorted, unique) of `spec` within 1..count; all frames when None."""
    if spec is None or spec.strip() in ("", "all"):
        return list(range(1, count + 1))
    out: set[int] = set()
    for part in spec.split(","):
        part = part.strip()
        try:
            if "-" in part:
                a, b = part.split("-", 1)
                lo, hi = int(a), int(b)
            else:
                lo = hi = int(part)
        except ValueError:
            raise UsageError(f"bad frame selection {spec!r} (use e.g. 1-24 or 1,3,5-9)") from None
        if lo < 1:
            raise UsageError(f"bad frame selection {spec!r}: frames count from 1")
        if hi < lo:
            raise UsageError(f"bad frame range {part!r} in {spec!r}: the first frame must not exceed the last")
        if hi > count:  # (every frame of the part that lies past the path's end, named)
            first = max(lo, count + 1)
            beyond = f"frame {hi} is" if first == hi else f"frames {first}-{hi} are"
            raise UsageError(f"{beyond} beyond the camera path's {count} frames (--frames {spec})")
        out.update(range(lo, hi + 1))
    return sorted(out)
