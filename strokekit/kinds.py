"""The line kinds and their codes in kind arrays, without numpy: the options (and the command
line's flags) name them without loading the model's arrays."""

from __future__ import annotations

#: Line kinds in layer order. The index is what `kind` arrays hold.
KINDS: tuple[str, ...] = ("silhouette", "border", "crease", "material", "nonmanifold",
                          "smooth_contour", "suggestive", "intersection")
KIND_INDEX = {k: i for i, k in enumerate(KINDS)}
N_KINDS = len(KINDS)
#: Hidden lines (LineOptions.occlusion) carry their occlusion level in the kind arrays: code =
#: kind + N_KINDS * level, so every stage that keeps kinds apart (chaining, the cleanup of doubled
#: lines, tracking's joins) keeps levels apart. int8 codes hold levels 0..15; deeper pieces count
#: as 15.
MAX_OCCLUSION = (127 - (N_KINDS - 1)) // N_KINDS


def layer_name(code: int) -> str:
    """The SVG layer (and glTF material) of a kind code: the kind, or hidden-<kind> for any level
    >= 1 (the levels of one kind share its hidden layer; the JSON gives each stroke's level)."""
    code = int(code)
    return KINDS[code % N_KINDS] if code < N_KINDS else "hidden-" + KINDS[code % N_KINDS]
