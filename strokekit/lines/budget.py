"""What a frame's line pass costs before it runs: its visibility samples and their memory, so
that a run no machine can do (a sample spacing of 1e-9 px wanted 33 TiB per frame) is refused
before any work, as the raster pass's is (raster.rays.check_raster_fits)."""

from __future__ import annotations

import os

import numpy as np

from strokekit.camera.view import Camera
from strokekit.errors import UsageError
from strokekit.lines.facing import FrameView
from strokekit.lines.features import wants_smooth_contours
from strokekit.lines.visibility import clip_segments
from strokekit.model import row_norm
from strokekit.options import LineOptions
from strokekit.scene.load import Scene

#: Peak bytes of a frame's line pass per visibility sample (samples, rays, hits, runs, chaining):
#: tracemalloc on the bunny's 8-frame orbit gave 325-340 at 0.05-0.25 px and ~500 at the default
#: 4 px (where the fixed costs weigh more).
BYTES_PER_SAMPLE = 400
#: Cameras of a run looked at: evenly spaced ones, and the one that shows the scene largest.
_CAMERAS_LOOKED_AT = 4


def visibility_samples(scene: Scene, camera: Camera, options: LineOptions) -> int:
    """About how many visibility samples the line pass takes for `camera`: per mesh feature edge
    (the camera-independent kinds asked for, and the camera's mesh contours) its length on screen
    inside the image / sample_spacing_px, plus one; one for an edge shorter than whole_edge_px.
    The lines inside faces (smooth and suggestive contours, intersections) count as another set
    of mesh contours each."""
    kinds = set(options.kinds)
    mask = np.zeros(len(scene.edges), bool)
    if "border" in kinds:
        mask |= scene.is_border
    if "nonmanifold" in kinds:
        mask |= scene.is_nonmanifold
    if "crease" in kinds:
        mask |= scene.crease_mask(options.crease_angle_deg)
    if "material" in kinds and len(scene.materials) > 1:
        mask |= scene.is_material_boundary
    inner = int(wants_smooth_contours(options)) + int("suggestive" in kinds) + int("intersection" in kinds)
    sil = FrameView(scene, camera).silhouettes if ("silhouette" in kinds or inner) else np.zeros_like(mask)
    mesh_sil = sil if "silhouette" in kinds and options.contours == "mesh" else np.zeros_like(mask)
    return _samples(scene, camera, options, mask | mesh_sil) + inner * _samples(scene, camera, options, sil)


def _samples(scene: Scene, camera: Camera, options: LineOptions, edges: np.ndarray) -> int:
    e = np.take(scene.edges, np.flatnonzero(edges), axis=0)
    if len(e) == 0:
        return 0
    a, b = np.take(scene.vertices, e[:, 0], axis=0), np.take(scene.vertices, e[:, 1], axis=0)
    t0, t1 = clip_segments(a, b, camera, camera.near_distance(scene.radius))
    keep = t1 > t0
    ab = (b - a)[keep]
    pa, _ = camera.project(a[keep] + t0[keep, None] * ab)
    pb, _ = camera.project(a[keep] + t1[keep, None] * ab)
    L = row_norm(pb - pa)
    n = np.where(L < options.whole_edge_px, 1.0, np.maximum(1.0, np.ceil(L / options.sample_spacing_px)) + 1.0)
    return int(min(n.sum(), 2.0 ** 62))


def _cameras_to_look_at(cameras: list[tuple[int, Camera]], scene: Scene) -> list[tuple[int, Camera]]:
    """A few of a run's (frame, camera): evenly spaced, and the one whose image shows the scene
    largest (focal length over the distance to the scene's near side)."""
    if len(cameras) <= _CAMERAS_LOOKED_AT + 1:
        return list(cameras)
    picks = set(np.linspace(0, len(cameras) - 1, _CAMERAS_LOOKED_AT).round().astype(int).tolist())
    eyes = np.array([c.eye for _, c in cameras], float)
    focal = np.array([c.focal_px for _, c in cameras], float)
    ortho = np.array([c.is_ortho for _, c in cameras], bool)
    dist = np.maximum(np.linalg.norm(eyes - scene.center, axis=1) - scene.radius, 1e-3 * scene.radius)
    scale = np.where(ortho, focal * scene.radius, focal * scene.radius / dist)
    picks.add(int(np.argmax(scale)))
    return [cameras[k] for k in sorted(picks)]


def machine_memory_bytes() -> int | None:
    """The machine's physical memory in bytes, or None where it is not known (not POSIX)."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):
        return None


def check_lines_fit(scene: Scene, cameras, options: LineOptions) -> None:
    """UsageError, before any work, when a frame's line pass would need more memory than the
    machine has (estimated by visibility_samples on a few of the run's (frame, camera))."""
    total = machine_memory_bytes()
    cameras = list(cameras)
    if total is None or not cameras:
        return
    # First a bound that needs no projection: every edge of the scene, each across the image.
    inner = int(wants_smooth_contours(options)) + int("suggestive" in options.kinds) + \
        int("intersection" in options.kinds)
    diag = max(float(np.hypot(c.width, c.height)) for _, c in cameras)
    if len(scene.edges) * (1 + inner) * (np.ceil(diag / options.sample_spacing_px) + 1) * BYTES_PER_SAMPLE <= total:
        return
    for frame, cam in _cameras_to_look_at(cameras, scene):
        n = visibility_samples(scene, cam, options)
        need = n * BYTES_PER_SAMPLE
        if need > total:
            raise UsageError(f"sample_spacing_px {options.sample_spacing_px:g} px: the line pass of frame {frame} "
                             f"needs about {n:.3g} visibility samples, {need / 2**30:.0f} GiB; this machine has "
                             f"{total / 2**30:.0f} GiB (a larger spacing or a smaller image)",
                             option="sample_spacing_px")
