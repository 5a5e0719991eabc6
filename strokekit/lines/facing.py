"""What one frame sees of the scene (`FrameView`): which faces face the eye, which it sees exactly
edge-on, which edges are contours. The line stages of a frame share them; each is built on first
use and kept with the view, so per-frame tables never live in the scene.

Facing is decided per face in float64 from the face plane (n . eye - n . centroid), one rule per
face, so two neighbours never disagree about a shared edge: a face with n.(eye - P) <= 0 counts
as back-facing."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from strokekit.camera.view import Camera
from strokekit.scene.load import Scene

#: A face is seen edge-on when the eye lies within this fraction of the eye's distance (plus the
#: scene radius) of its plane (parallel cameras: the rays' direction within this of its plane):
#: float64 rounding of an exactly edge-on face (the eye in a model's symmetry plane) and nothing
#: a pixel could show (at 1e-12 rad a face 1e6 px long is 1e-6 px wide).
EDGE_ON_TOL = 1e-12


@dataclass(frozen=True, eq=False)
class FrameView:
    """The scene seen by one camera. Its tables are read-only arrays."""

    scene: Scene
    camera: Camera

    @cached_property
    def _facing(self) -> tuple[np.ndarray, np.ndarray]:
        scene, camera = self.scene, self.camera
        n = scene.face_normals
        if camera.is_ortho:
            d = camera.ray_dir  # (fwd but for the oblique projections: their rays' direction)
            g = n @ -d
            tol = EDGE_ON_TOL * float(np.linalg.norm(d))
        else:
            # n.eye - offset > 0 (a difference of doubles is 0 only when they are equal).
            eye = np.asarray(camera.eye, float)
            g = n @ eye - scene.face_offsets
            tol = EDGE_ON_TOL * float(np.linalg.norm(eye - scene.center) + scene.radius)
        ff = g > tol
        on = np.abs(g) <= tol
        ff.setflags(write=False)
        on.setflags(write=False)
        return ff, on

    @property
    def front_facing(self) -> np.ndarray:
        """(F,) True where the face's front side faces the eye (perspective) or the view (ortho).
        A face seen exactly edge-on (`edge_on`) faces neither way and counts as back-facing,
        whatever the rounding of its n.(eye - P) says."""
        return self._facing[0]

    @property
    def edge_on(self) -> np.ndarray:
        """(F,) True where the frame sees the face exactly edge-on (EDGE_ON_TOL): the eye in its
        plane, or for a parallel camera the projection rays along it. Such a face covers no area
        and hides nothing: the renderer leaves it out of the occlusion rays, and it counts as
        back-facing."""
        return self._facing[1]

    @cached_property
    def silhouettes(self) -> np.ndarray:
        """(E,) manifold edges whose two faces face opposite ways (the mesh contours)."""
        ff = np.append(self.front_facing, False)
        f0, f1 = self.scene.manifold_face_pairs
        mask = np.take(ff, f0, mode="wrap") != np.take(ff, f1, mode="wrap")  # in range: no bounds check
        mask.setflags(write=False)
        return mask
