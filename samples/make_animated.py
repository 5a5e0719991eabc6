"""Write two animated glTF scenes into a folder, for docs/animation.md:

- turntable.glb: spot (../shared/models/spot.obj) on a turntable, a node turning 3 degrees a
  frame about +Y at 24 fps (120 frames, a whole turn);
- bend.glb: a skinned tube whose second joint bends it 60 degrees over 24 frames.

    python samples/make_animated.py OUT
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from animated import skinned_tube_glb, turntable_glb  # noqa: E402

from strokekit.scene.load import load_scene  # noqa: E402


def main() -> None:
    out = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
    out.mkdir(parents=True, exist_ok=True)
    spot = load_scene(ROOT.parent / "shared" / "models" / "spot.obj")
    turntable_glb(out / "turntable.glb", spot.vertices - spot.center, spot.faces, frames=120)
    skinned_tube_glb(out / "bend.glb", frames=24)
    print(f"wrote {out / 'turntable.glb'} and {out / 'bend.glb'}")


if __name__ == "__main__":
    main()
