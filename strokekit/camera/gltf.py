"""Camera paths from a glTF/GLB file's camera node: the node's world transform through its
ancestors, its animation sampled at 24 fps (rotations slerped), its lens."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from strokekit.animation import GltfData, NodeTree, field_of, frame_times, load_gltf, read_channels, time_span
from strokekit.camera.view import MAX_IMAGE_PX, MAX_PATH_FRAMES, Camera, CameraPath
from strokekit.errors import InputError


def gltf_camera_count(path) -> int:
    """Number of camera nodes (nodes placing a camera) of a glTF/GLB file: what `--camera FILE`
    can use (0 when the file cannot be read)."""
    import pygltflib

    try:
        g = pygltflib.GLTF2().load(str(path))
    except Exception:  # info only: the scene loader reports broken files
        return 0
    return sum(1 for n in g.nodes or [] if n.camera is not None)


# --- glTF camera nodes and their animation -------------------------------------------------------

def _gltf_width(height: int, aspect: float, what: str) -> int:
    """Image width height x aspect of a glTF lens, refused outside 1..MAX_IMAGE_PX."""
    w = height * aspect
    if not 0.5 <= w < MAX_IMAGE_PX + 0.5:
        raise InputError(f"{what} gives an image {w:.4g} x {height} px: the width must be 1 to {MAX_IMAGE_PX} px")
    return int(round(w))


def _camera_at(m: np.ndarray, cam, width: int | None, height: int | None) -> Camera:
    """The Camera of glTF camera object `cam` placed by world matrix m (local -Z forward, +Y up)."""
    rot = m[:3, :3]
    with np.errstate(over="ignore", under="ignore"):
        scale = np.linalg.norm(rot, axis=0)
    if not np.all(np.isfinite(scale) & (scale > 0)):  # a scale of 1e300 (or 1e-300) squared: the
        peak = np.max(np.abs(rot), axis=0)  # columns brought near 1 first, then normalized
        rot = rot / np.where(peak > 0, peak, 1)
        scale = np.linalg.norm(rot, axis=0)
    rot = rot / np.where(scale > 0, scale, 1)
    eye = m[:3, 3]
    fwd, up = -rot[:, 2], rot[:, 1]
    if cam.type == "orthographic":  # (gltf_camera_path checked that the block is there)
        xmag, ymag = cam.orthographic.xmag, cam.orthographic.ymag
        if not all(isinstance(v, (int, float)) and math.isfinite(v) and v > 0 for v in (xmag, ymag)):
            raise InputError(f"orthographic xmag and ymag must be > 0, got {xmag!r} and {ymag!r}")
        h = height or 1024
        w = width or _gltf_width(h, xmag / ymag, f"orthographic xmag / ymag ({xmag:g} / {ymag:g})")
        return Camera(eye=tuple(eye), target=tuple(eye + fwd), up=tuple(up), projection="orthographic",
                      ortho_height=2 * cam.orthographic.ymag, width=w, height=h)
    p = cam.perspective
    if not (isinstance(p.yfov, (int, float)) and math.isfinite(p.yfov) and 0 < p.yfov < math.pi):
        raise InputError(f"perspective camera needs a yfov in (0, pi) radians, got {p.yfov!r}")
    h = height or 1024
    aspect = p.aspectRatio if p.aspectRatio is not None else 1.0
    if not (isinstance(aspect, (int, float)) and math.isfinite(aspect) and aspect > 0):
        raise InputError(f"perspective aspectRatio must be a number > 0, got {aspect!r}")
    w = width or _gltf_width(h, aspect, f"perspective aspectRatio {aspect:g}")
    return Camera(eye=tuple(eye), target=tuple(eye + fwd), up=tuple(up),
                  fov_y=math.degrees(p.yfov), width=w, height=h, near=(p.znear or None))


def gltf_camera_path(path: Path, width: int | None = None, height: int | None = None,
                     fps: float = 24.0) -> CameraPath:
    """The first camera node of a glTF/GLB file (in node order), placed by its world transform,
    following its node animation when there is one.

    glTF cameras look down their local -Z with +Y up. Perspective: fov_y = yfov (radians in the
    file, degrees in Camera), width = height x aspectRatio unless given; orthographic: ortho_height
    = 2 ymag. Height defaults to 1024.

    Animation: the first animation (in file order) with a translation, rotation or scale channel
    targeting the camera node or one of its ancestors drives the camera; other animations are
    ignored, and so are properties no channel of it targets (they keep their rest values). The
    channels (LINEAR, with slerp for rotations; STEP; CUBICSPLINE) are sampled at `fps`: frame k at
    time t0 + k / fps for k = 0, 1, ... while the time is at most t1 (up to float32 rounding of the
    key times), t0 and t1 the earliest and latest key times of that animation's channels that affect
    the camera. So the last key time is a frame whenever t1 - t0 is a whole number of frames.
    Before its first key a channel holds its first value, after its last key its last value. The
    world transform is composed per frame; the lens does not animate (glTF cannot without
    extensions). Without such an animation the node's rest transform gives one frame.

    Accessors may be float or normalized integers, in a GLB binary chunk, a data URI or an external
    file, strided or sparse. Anything malformed is one InputError naming the file."""
    path = Path(path)
    if not (isinstance(fps, (int, float)) and math.isfinite(fps) and fps > 0):
        raise InputError(f"fps must be > 0, got {fps!r}", path)
    g = load_gltf(path)
    if not g.cameras:
        raise InputError("glTF file has no camera", path)
    nodes = g.nodes or []
    data = GltfData(g, path)
    cam_i = next((i for i, n in enumerate(nodes) if n.camera is not None), None)
    if cam_i is None:
        raise InputError("glTF file has cameras but no node uses one", path)
    cam_obj = data.item("cameras", nodes[cam_i].camera, f"node {cam_i}")
    # The lens is the block named by the type; without it the camera would be a guess (an
    # orthographic camera without one was drawn in perspective at 40 degrees).
    kind = field_of(cam_obj, "type")
    if kind not in ("perspective", "orthographic"):
        raise data.error(f"camera {nodes[cam_i].camera} has type {kind!r}: glTF cameras are 'perspective' or "
                         f"'orthographic'")
    if field_of(cam_obj, kind) is None:
        needs = "yfov" if kind == "perspective" else "xmag, ymag"
        raise data.error(f"camera {nodes[cam_i].camera} is {kind} but has no '{kind}' block ({needs})")
    tree = NodeTree(g, data)
    chain = tree.chain(cam_i)  # camera node, its parent, ..., the root

    channels = _camera_channels(g, data, set(chain))
    if channels:
        t0, t1 = time_span(channels)
        times = frame_times(t0, t1, fps, MAX_PATH_FRAMES, "camera animation", path)
    else:
        times = np.zeros(1)
    world = tree.world(cam_i, channels, times)
    if not np.all(np.isfinite(world)):
        raise InputError(f"the world transform of camera node {cam_i} is out of range (its nodes' scales and "
                         "translations multiply beyond float64)", path)

    cams = []
    for k, m in enumerate(world):
        try:
            cams.append(_camera_at(m, cam_obj, width, height))
        except InputError as e:
            where = f"frame {k + 1} (t = {times[k]:g} s)" if channels else f"node {cam_i}"
            raise InputError(f"camera at {where}: {e}", path) from None
    return CameraPath(cameras=tuple(cams), fps=float(fps), source=str(path))


def _camera_channels(g, data: GltfData, chain: set[int]) -> dict:
    """{(node, path): Channel} of the first animation with a TRS channel on a node of `chain`; {}
    when none has one (strokekit.animation.read_channels checks them)."""
    for ai, anim in enumerate(g.animations or []):
        hits = [ch for ch in (anim.channels or [])
                if field_of(field_of(ch, "target"), "node") in chain and field_of(field_of(ch, "target"), "path")
                in ("translation", "rotation", "scale")]
        if hits:
            return read_channels(g, data, ai, nodes=chain)
    return {}
