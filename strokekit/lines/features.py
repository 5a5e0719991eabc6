"""Feature edges of one frame: silhouette, border, crease, material, non-manifold, and the lines
inside faces: smooth contours (contours.py), suggestive contours (suggestive.py) and
intersection lines (intersections.py). All vectorized over the scene's edges; which faces face
the eye is the frame's (facing.py)."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from strokekit.lines.contours import smooth_contours
from strokekit.lines.facing import FrameView
from strokekit.lines.intersections import intersection_edges
from strokekit.lines.suggestive import SMOOTH_PASSES, suggestive_contour_edges
from strokekit.lines.surface import surface_lift
from strokekit.model import KIND_INDEX, FeatureEdges
from strokekit.options import LineOptions
from strokekit.scene.load import Scene


@dataclass(frozen=True, eq=False)
class StaticFeatures:
    """What the feature edges of every frame share, built once per scene and options: each edge's
    kind among those that do not depend on the camera, by priority (kind (E,) int8, -1 none,
    read-only), and the intersection lines (None when not asked for)."""

    kind: np.ndarray
    intersections: FeatureEdges | None


def static_features(scene: Scene, options: LineOptions) -> StaticFeatures:
    """The frames' StaticFeatures, and the scene tables the lines asked for built now, so that no
    frame pays for them: vertex normals, normals split at creases and the face -> edge table
    (smooth contours), curvature tensors (suggestive)."""
    masks = {}
    if "border" in options.kinds:
        masks["border"] = scene.is_border
    if "nonmanifold" in options.kinds:
        masks["nonmanifold"] = scene.is_nonmanifold
    if "crease" in options.kinds:
        masks["crease"] = scene.crease_mask(options.crease_angle_deg)
    if "material" in options.kinds and len(scene.materials) > 1:
        masks["material"] = scene.is_material_boundary
    kind = np.full(len(scene.edges), -1, np.int8)
    # Lowest priority first so that higher kinds overwrite.
    for name in ("material", "crease", "nonmanifold", "border"):
        if name in masks:
            kind[masks[name]] = KIND_INDEX[name]
    kind.setflags(write=False)
    if wants_smooth_contours(options) or "suggestive" in options.kinds:
        scene.face_edges, scene.face_scale(), scene.face_size
    if wants_smooth_contours(options):
        scene.split_normals(options.crease_angle_deg), scene.face_scale(options.crease_angle_deg)
    if "suggestive" in options.kinds:
        scene.curvature_tensors(SMOOTH_PASSES)
    return StaticFeatures(kind, intersection_edges(scene) if "intersection" in options.kinds else None)


def feature_edges(view: FrameView, options: LineOptions, static: StaticFeatures | None = None,
                  with_lift: bool = False) -> FeatureEdges:
    """Candidate feature edges of the frame. Each mesh edge gets one kind, in priority order
    silhouette > border > nonmanifold > crease > material; then the lines inside faces, each with
    its own occlusion-ray lift: smooth contours (`wants_smooth_contours`; they replace the mesh
    silhouettes when contours == "smooth"), suggestive contours and intersection lines, when
    their kinds are selected. Their va/vb chaining keys are >= V (or -1 where a stroke must end),
    except the smooth contour's pieces along sharp edges (contours.sharp_edge_contours), which
    meet each other at mesh vertex ids; a mesh edge such a piece covers whole gets no other kind,
    as a mesh silhouette edge gets none. `with_lift`: also give the mesh edges their occlusion-ray
    lift (lines.surface_lift) when no other part brings one."""
    scene = view.scene
    static = static_features(scene, options) if static is None else static
    static_kind = static.kind
    mesh_silhouettes = "silhouette" in options.kinds and options.contours == "mesh"
    smooth = None
    if wants_smooth_contours(options):
        kind = static_kind.copy()
        if mesh_silhouettes:
            kind[np.flatnonzero(view.silhouettes)] = KIND_INDEX["silhouette"]
        smooth, whole = smooth_contours(view, crease_angle_deg=options.crease_angle_deg,
                                        occlusion_offset=options.occlusion_offset)
        # The contour takes the whole edge from the lower kinds (as a mesh silhouette does; a mesh
        # silhouette drawn beside smooth contours keeps its edge).
        kind[whole] = np.where(kind[whole] == KIND_INDEX["silhouette"], kind[whole], -1)
        sel = np.flatnonzero(kind >= 0)
        kind_sel = kind[sel]
    elif mesh_silhouettes:
        # Silhouette over the static kinds, without writing an array of every edge.
        sil_mask = view.silhouettes
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
        ff = view.front_facing
        second_front = ff[ef[sil, 1]]
        face[sil] = np.where(second_front, ef[sil, 1], ef[sil, 0])
    v = scene.vertices
    mesh = FeatureEdges(a=np.take(v, e[:, 0], axis=0), b=np.take(v, e[:, 1], axis=0), kind=kind_sel, va=e[:, 0].astype(np.int64),
                        vb=e[:, 1].astype(np.int64), face=face)
    parts = [mesh]
    if smooth is not None:
        parts.append(smooth)
    if "suggestive" in options.kinds:
        parts.append(suggestive_contour_edges(view, options))
    if "intersection" in options.kinds:
        parts.append(static.intersections if static.intersections is not None else intersection_edges(scene))
    if len(parts) == 1 and not with_lift:
        return mesh
    if len(mesh) or len(parts) == 1:
        # Lines inside faces bring their own lift, so the concatenation has one and the renderer
        # would not add the mesh edges' lift (it only fills a missing one): add it here.

        parts[0] = replace(mesh, lift=surface_lift(view, mesh, options.occlusion_offset, edge_index=sel,
                                                   edge_faces=ef))
    if len(parts) == 1:
        return parts[0]
    return FeatureEdges.concat(parts)


def wants_smooth_contours(options: LineOptions) -> bool:
    """Smooth contours are drawn when asked for by kind, or when `contours == "smooth"` and
    silhouettes are asked for (they then replace the mesh silhouettes)."""
    return "smooth_contour" in options.kinds or (options.contours == "smooth" and "silhouette" in options.kinds)
