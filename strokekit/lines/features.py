"""Feature edges of one frame (BRIEF 2): silhouette, border, crease, material, non-manifold, and
the lines inside faces: smooth contours (contours.py), suggestive contours (suggestive.py) and
intersection lines (intersections.py).

All vectorized over the scene's edges. Facing is decided per face in float64 from the face plane
(n . eye - n . centroid), one rule per face, so two neighbours never disagree about a shared
edge-on face: a face with n.(eye - P) <= 0 counts as back-facing."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from strokekit.camera.view import Camera
from strokekit.lines.contours import smooth_contours
from strokekit.lines.intersections import intersection_edges
from strokekit.lines.suggestive import SMOOTH_PASSES, curvature_tensors, suggestive_contour_edges
from strokekit.lines.surface import front_facing, surface_lift
from strokekit.model import KIND_INDEX, FeatureEdges
from strokekit.options import LineOptions
from strokekit.scene.load import Scene
from strokekit.scene.tables import face_edges, face_scale, face_size, scene_cache, split_normals


def _manifold_face_pairs(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """(E,) int32 first and second face of each manifold edge, F (one past the last face) elsewhere:
    index a facing array padded with one False to compare the two faces of every edge at once."""
    c = scene_cache(scene)
    pairs = c.get("manifold_face_pairs")
    if pairs is None:
        F = len(scene.faces)
        m = scene.is_manifold
        ef = scene.edge_faces
        pairs = (np.where(m, ef[:, 0], F).astype(np.intp), np.where(m, ef[:, 1], F).astype(np.intp))
        c["manifold_face_pairs"] = pairs
    return pairs


def static_feature_mask(scene: Scene, options: LineOptions) -> dict[str, np.ndarray]:
    """Edge masks of the kinds that do not depend on the camera (computed once per scene)."""
    out = {}
    if "border" in options.kinds:
        out["border"] = scene.is_border
    if "nonmanifold" in options.kinds:
        out["nonmanifold"] = scene.is_nonmanifold
    if "crease" in options.kinds:
        out["crease"] = scene.crease_mask(options.crease_angle_deg)
    if "material" in options.kinds and len(scene.materials) > 1:
        out["material"] = scene.is_material_boundary
    # Warm the per-scene caches of the lines inside faces now, so no frame pays for them: vertex
    # normals, normals split at creases and the face -> edge table (smooth contours), curvature
    # tensors (suggestive), the intersection segments (BVH + narrow phase). They live in
    # scene_cache(scene).
    if wants_smooth_contours(options) or "suggestive" in options.kinds:
        face_edges(scene), face_scale(scene), face_size(scene)
    if wants_smooth_contours(options):
        split_normals(scene, options.crease_angle_deg), face_scale(scene, options.crease_angle_deg)
    if "suggestive" in options.kinds:
        curvature_tensors(scene, SMOOTH_PASSES)
    if "intersection" in options.kinds:
        intersection_edges(scene)
    return out


def _static_kinds(scene: Scene, static: dict[str, np.ndarray]) -> np.ndarray:
    """(E,) int8 kind of every edge from the camera-independent masks (-1: none), by priority;
    kept in `static` under "_kinds" (read-only), as the masks are kept for many frames."""
    kind = static.get("_kinds")
    if kind is None:
        kind = np.full(len(scene.edges), -1, np.int8)
        # Lowest priority first so that higher kinds overwrite.
        for name in ("material", "crease", "nonmanifold", "border"):
            if name in static:
                kind[static[name]] = KIND_INDEX[name]
        kind.setflags(write=False)
        static["_kinds"] = kind
    return kind


def silhouette_mask(scene: Scene, camera: Camera) -> np.ndarray:
    """(E,) manifold edges whose two faces face opposite ways. Read-only; the last camera's
    answer is kept per scene (the hidden-line pass asks again for the outline)."""
    c = scene_cache(scene)
    last = c.get("silhouette_mask")
    if last is not None and last[0] is camera:
        return last[1]
    ff = np.append(front_facing(scene, camera), False)
    f0, f1 = _manifold_face_pairs(scene)
    mask = np.take(ff, f0, mode="wrap") != np.take(ff, f1, mode="wrap")  # in range: no bounds check
    mask.setflags(write=False)
    c["silhouette_mask"] = (camera, mask)
    return mask


def feature_edges(scene: Scene, camera: Camera, options: LineOptions,
                  static: dict[str, np.ndarray] | None = None, with_lift: bool = False) -> FeatureEdges:
    """Candidate feature edges for this camera. Each mesh edge gets one kind, in priority order
    silhouette > border > nonmanifold > crease > material; then the lines inside faces, each with
    its own occlusion-ray lift: smooth contours (`wants_smooth_contours`; they replace the mesh
    silhouettes when contours == "smooth"), suggestive contours and intersection lines, when
    their kinds are selected. Their va/vb chaining keys are >= V (or -1 where a stroke must end),
    except the smooth contour's pieces along sharp edges (contours.sharp_edge_contours), which
    meet each other at mesh vertex ids; a mesh edge such a piece covers whole gets no other kind,
    as a mesh silhouette edge gets none. `with_lift`: also give the mesh edges their occlusion-ray
    lift (lines.surface_lift) when no other part brings one."""
    static = static_feature_mask(scene, options) if static is None else static
    static_kind = _static_kinds(scene, static)
    mesh_silhouettes = "silhouette" in options.kinds and options.contours == "mesh"
    smooth = None
    if wants_smooth_contours(options):
        kind = static_kind.copy()
        if mesh_silhouettes:
            kind[np.flatnonzero(silhouette_mask(scene, camera))] = KIND_INDEX["silhouette"]
        smooth, whole = smooth_contours(scene, camera, crease_angle_deg=options.crease_angle_deg,
                                        occlusion_offset=options.occlusion_offset)
        # The contour takes the whole edge from the lower kinds (as a mesh silhouette does; a mesh
        # silhouette drawn beside smooth contours keeps its edge).
        kind[whole] = np.where(kind[whole] == KIND_INDEX["silhouette"], kind[whole], -1)
        sel = np.flatnonzero(kind >= 0)
        kind_sel = kind[sel]
    elif mesh_silhouettes:
        # Silhouette over the static kinds, without writing an array of every edge.
        sil_mask = silhouette_mask(scene, camera)
        sel = np.flatnonzero(sil_mask | (static_kind >= 0))
        kind_sel = np.where(sil_mask[sel], np.int8(KIND_INDEX["silhouette"]), static_kind[sel])
    else:
        sel = np.flatnonzero(static_kind >= 0)
        kind_sel = static_kind[sel]
    e = np.take(scene.edges, sel, axis=0)
    # The face on the front side carries the surface point of a silhouette; the first face otherwise.
    ef = np.take(scene.edge_faces, sel, axis=0)
    face = ef[:, 0].copy()
    sil = kind_sel == KIND_INDEX["silhouette"]
    if sil.any():
        ff = front_facing(scene, camera)
        second_front = ff[ef[sil, 1]]
        face[sil] = np.where(second_front, ef[sil, 1], ef[sil, 0])
    v = scene.vertices
    mesh = FeatureEdges(a=np.take(v, e[:, 0], axis=0), b=np.take(v, e[:, 1], axis=0), kind=kind_sel, va=e[:, 0].astype(np.int64),
                        vb=e[:, 1].astype(np.int64), face=face)
    parts = [mesh]
    if smooth is not None:
        parts.append(smooth)
    if "suggestive" in options.kinds:
        parts.append(suggestive_contour_edges(scene, camera, options))
    if "intersection" in options.kinds:
        parts.append(intersection_edges(scene))
    if len(parts) == 1 and not with_lift:
        return mesh
    if len(mesh) or len(parts) == 1:
        # Lines inside faces bring their own lift, so the concatenation has one and the renderer
        # would not add the mesh edges' lift (it only fills a missing one): add it here.

        parts[0] = replace(mesh, lift=surface_lift(scene, mesh, camera, options.occlusion_offset, edge_index=sel,
                                                   edge_faces=ef))
    if len(parts) == 1:
        return parts[0]
    return FeatureEdges.concat(parts)


def wants_smooth_contours(options: LineOptions) -> bool:
    """Smooth contours are drawn when asked for by kind, or when `contours == "smooth"` and
    silhouettes are asked for (they then replace the mesh silhouettes)."""
    return "smooth_contour" in options.kinds or (options.contours == "smooth" and "silhouette" in options.kinds)
