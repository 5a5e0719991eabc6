"""Scene loading: any mesh file flattened to one welded triangle soup in world space.

A `Scene` holds float64 world vertices welded by position, faces, a per-face object id and
material id, and cached topology (edges, their faces, static edge kinds). UV and normal seams
disappear in the weld, so they never become borders. Degenerate and duplicate faces are dropped
from the scene and counted.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import re
import struct
from dataclasses import dataclass, replace
from functools import cached_property
from pathlib import Path
from urllib.parse import unquote

import numpy as np

from strokekit.animation import GltfData, load_gltf
from strokekit.errors import InputError, hold_interrupts
from strokekit.fileio import atomic_write_bytes
from strokekit.scene.motion import SceneMotion, ScenePose
from strokekit.scene.obj_faces import face_past_vertices, short_face_warnings
from strokekit.scene.tables import (
    SceneTables,
    bounds_of,
    dihedral_cos_of,
    face_normals_of,
    face_offsets_of,
    row_norms,
)
from strokekit.scene.weld import Welded, weld

SUPPORTED = (".obj", ".ply", ".stl", ".glb", ".gltf", ".off")


@dataclass(frozen=True)
class Material:
    name: str
    base_color: tuple[float, float, float, float] = (0.8, 0.8, 0.8, 1.0)


@dataclass(frozen=True, eq=False)
class Scene(SceneTables):
    """World-space triangle scene. vertices (V, 3) float64, faces (F, 3) int64,
    face_object (F,) int32 indices into `objects`, face_material (F,) int32 into `materials`.
    Its derived tables (normals, topology, `SceneTables`) are built on first use and kept."""

    vertices: np.ndarray
    faces: np.ndarray
    face_object: np.ndarray
    face_material: np.ndarray
    objects: tuple[str, ...] = ()
    materials: tuple[Material, ...] = ()
    source: str = ""
    dropped_degenerate: int = 0
    dropped_duplicate: int = 0
    input_vertices: int = 0
    #: What is wrong with the file but does not change the drawing, one sentence each naming the
    #: file (a .gltf whose texture image is missing): the command line prints them as warnings.
    warnings: tuple[str, ...] = ()
    #: How the objects move (a glTF file's animations, skins, morph targets), None for a still
    #: scene; `at` poses the scene.
    motion: SceneMotion | None = None
    #: Where the objects are in this scene (None: at rest, as the file places them).
    pose: ScenePose | None = None

    def framing(self, animation: str | None = None) -> tuple[np.ndarray, float, np.ndarray]:
        """(centre (3,), radius, points (N, 3)) that frame the scene for a camera: its own, or for
        a moving scene those over its whole animation `animation` (a name or number; None: the
        first), the points of its poses at SceneMotion.sample_times."""
        m = self.motion
        ai = m.animation(animation) if m is not None else None
        if m is None or not m.moves(ai):
            return self.center, self.radius, self.vertices
        _, c, r = m.extent(ai)
        times = m.sample_times(ai)
        pick = times[np.unique(np.linspace(0, len(times) - 1, min(len(times), 64)).round().astype(int))]
        used = m.rest.vertex_of >= 0
        return c, r, np.concatenate([m.file_vertices_at(ai, float(t))[used] for t in pick])

    def at(self, time: float, animation: int | None = 0) -> Scene:
        """The scene at `time` seconds of its motion's animation `animation` (an index; None: no
        animation, the objects in their rest pose): the scene itself when nothing moves."""
        if self.motion is None:
            return self
        return self.motion.posed(self, animation, time)

    # --- geometry --------------------------------------------------------------------------
    @cached_property
    def bounds(self) -> np.ndarray:
        """(2, 3) min and max corners."""
        return bounds_of(self.vertices)

    @cached_property
    def center(self) -> np.ndarray:
        return self.bounds.mean(axis=0)

    @cached_property
    def radius(self) -> float:
        """Radius of the bounding sphere around `center` (world units); > 0 for any non-empty scene."""
        r = float(row_norms(self.vertices - self.center).max())
        return r if r > 0 else 1.0

    @cached_property
    def face_vertex_ids(self) -> np.ndarray:
        """(U,) the vertices some face uses, ascending."""
        return np.unique(self.faces)

    @cached_property
    def face_vertices(self) -> np.ndarray:
        """(U, 3) those vertices' coordinates (all of `vertices` when every one is used)."""
        ids = self.face_vertex_ids
        return self.vertices if len(ids) == len(self.vertices) else self.vertices[ids]

    @cached_property
    def face_normals(self) -> np.ndarray:
        """(F, 3) unit normals from the winding, float64. Degenerate faces were dropped, so no NaN."""
        return face_normals_of(self.vertices, self.faces)

    @cached_property
    def face_normal_rows(self) -> np.ndarray:
        """(3, F) face_normals as contiguous rows (for column-wise arithmetic on (3, N) arrays)."""
        return np.ascontiguousarray(self.face_normals.T)

    @cached_property
    def face_offsets(self) -> np.ndarray:
        """(F,) plane offsets n.P for the face centroid: facing(eye) = sign(n.eye - offset)."""
        return face_offsets_of(self.vertices, self.faces, self.face_normals)

    @cached_property
    def face_areas(self) -> np.ndarray:
        v = self.vertices
        a = v[self.faces[:, 0]]
        return 0.5 * np.linalg.norm(np.cross(v[self.faces[:, 1]] - a, v[self.faces[:, 2]] - a), axis=1)

    # --- topology --------------------------------------------------------------------------
    @cached_property
    def edges(self) -> np.ndarray:
        """(E, 2) unique undirected edges, vertex ids sorted within each row, rows sorted."""
        return self._topology[0]

    @cached_property
    def edge_faces(self) -> np.ndarray:
        """(E, 2) the first two faces of each edge; -1 where the edge has fewer."""
        return self._topology[1]

    @cached_property
    def edge_face_count(self) -> np.ndarray:
        """(E,) how many faces use each edge: 1 border, 2 manifold, > 2 non-manifold."""
        return self._topology[2]

    @cached_property
    def _topology(self):
        f = self.faces
        half = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
        face_of = np.tile(np.arange(len(f)), 3)
        half.sort(axis=1)
        key = half[:, 0].astype(np.int64) * (len(self.vertices) + 1) + half[:, 1]
        order = np.argsort(key, kind="stable")
        key_sorted = key[order]
        starts = np.flatnonzero(np.r_[True, key_sorted[1:] != key_sorted[:-1]])
        counts = np.diff(np.r_[starts, len(key_sorted)])
        edges = half[order[starts]]
        ef = np.full((len(starts), 2), -1, dtype=np.int64)
        ef[:, 0] = face_of[order[starts]]
        two = counts >= 2
        ef[two, 1] = face_of[order[starts[two] + 1]]
        return edges, ef, counts

    @cached_property
    def dihedral_cos(self) -> np.ndarray:
        """(E,) cosine of the angle between the two face normals of each manifold edge (1 elsewhere)."""
        return dihedral_cos_of(self.edge_faces, self.face_normals)

    @cached_property
    def is_border(self) -> np.ndarray:
        return self.edge_face_count == 1

    @cached_property
    def is_nonmanifold(self) -> np.ndarray:
        return self.edge_face_count > 2

    @cached_property
    def is_manifold(self) -> np.ndarray:
        return self.edge_face_count == 2

    @cached_property
    def is_material_boundary(self) -> np.ndarray:
        ef = self.edge_faces
        ok = self.is_manifold
        out = np.zeros(len(ef), bool)
        out[ok] = self.face_material[ef[ok, 0]] != self.face_material[ef[ok, 1]]
        return out

    def crease_mask(self, threshold_deg: float) -> np.ndarray:
        """(E,) manifold edges whose face normals differ by more than `threshold_deg` degrees."""
        return self.is_manifold & (self.dihedral_cos < np.cos(np.radians(threshold_deg)))

    @cached_property
    def content_hash(self) -> str:
        h = hashlib.sha256()
        for a in (self.vertices, self.faces, self.face_object, self.face_material):
            h.update(np.ascontiguousarray(a).tobytes())
        return h.hexdigest()[:16]

    def summary(self) -> dict:
        """What `strokekit info` prints: counts, bounds and what lines the scene can have."""
        return {
            "source": self.source,
            "objects": len(self.objects),
            "object_names": list(self.objects),
            "materials": [m.name for m in self.materials],
            "faces": int(len(self.faces)),
            "vertices_welded": int(len(self.vertices)),
            "vertices_in_file": int(self.input_vertices),
            "dropped_degenerate_faces": int(self.dropped_degenerate),
            "dropped_duplicate_faces": int(self.dropped_duplicate),
            "bounds_min": [float(x) for x in self.bounds[0]],
            "bounds_max": [float(x) for x in self.bounds[1]],
            "edges": int(len(self.edges)),
            "border_edges": int(self.is_border.sum()),
            "nonmanifold_edges": int(self.is_nonmanifold.sum()),
            "crease_edges_60deg": int(self.crease_mask(60.0).sum()),
            "material_boundary_edges": int(self.is_material_boundary.sum()),
            "line_kinds": self.available_kinds(),
            **({"animations": [{"index": a.index, "name": a.name, "start": a.start, "end": a.end,
                                "seconds": a.end - a.start, "moves": self.motion.moves(a.index)}
                               for a in self.motion.animations]} if self.motion is not None else {}),
        }

    def available_kinds(self, crease_deg: float = 60.0) -> list[str]:
        kinds = ["silhouette"] if self.is_manifold.any() else []
        if self.is_border.any():
            kinds.append("border")
        if self.crease_mask(crease_deg).any():
            kinds.append("crease")
        if self.is_material_boundary.any():
            kinds.append("material")
        if self.is_nonmanifold.any():
            kinds.append("nonmanifold")
        return kinds


def build_scene(vertices: np.ndarray, faces: np.ndarray, face_object: np.ndarray | None = None,
                face_material: np.ndarray | None = None, *, objects=("mesh",), materials=(Material("default"),),
                source: str = "", warnings: tuple[str, ...] = ()) -> Scene:
    """Weld vertices by position, drop degenerate and duplicate faces, return a Scene.

    vertices (V, 3) world units; faces (F, 3) vertex indices."""
    return _scene_of(weld(vertices, faces, source), len(np.asarray(vertices).reshape(-1, 3)), face_object,
                     face_material, objects=objects, materials=materials, source=source, warnings=warnings)


def _scene_of(w: Welded, input_vertices: int, face_object, face_material, **fields) -> Scene:
    n = len(w.kept) + w.dropped_degenerate + w.dropped_duplicate
    fo = np.zeros(n, np.int32) if face_object is None else np.asarray(face_object, np.int32)
    fm = np.zeros(n, np.int32) if face_material is None else np.asarray(face_material, np.int32)
    return Scene(vertices=w.vertices, faces=w.faces, face_object=fo[w.kept], face_material=fm[w.kept],
                 dropped_degenerate=w.dropped_degenerate, dropped_duplicate=w.dropped_duplicate,
                 input_vertices=input_vertices, **{k: tuple(v) if k != "source" else v for k, v in fields.items()})


def _material_of(geom) -> Material:
    vis = getattr(geom, "visual", None)
    mat = getattr(vis, "material", None)
    if mat is None:
        return Material("default")
    name = getattr(mat, "name", None) or "material"
    color = None
    for attr in ("baseColorFactor", "main_color", "diffuse"):
        c = getattr(mat, attr, None)
        if c is not None:
            c = np.asarray(c).ravel()
            if c.size >= 3:
                # trimesh hands colours back as uint8 (0-255) whatever the file held; floats are
                # taken as 0-1 unless they are out of that range.
                integer = np.issubdtype(c.dtype, np.integer)
                c = c.astype(float)
                if integer or c.max() > 1.0:
                    c = c / 255.0
                color = tuple(float(x) for x in (list(c[:3]) + [float(c[3]) if c.size > 3 else 1.0]))
                break
    return Material(str(name), color or (0.8, 0.8, 0.8, 1.0))


def load_scene(path: str | Path) -> Scene:
    """Load OBJ, PLY, STL, OFF or glTF/GLB into a world-space Scene (node transforms applied).

    Raises InputError with one clear line for missing, empty, unknown or broken files."""
    p = Path(path)
    if not p.exists():
        raise InputError("file not found", p)
    if p.is_dir():
        raise InputError("is a directory, not a mesh file", p)
    if p.suffix.lower() not in SUPPORTED:
        raise InputError(f"unknown mesh format '{p.suffix}' (supported: {', '.join(SUPPORTED)})", p)
    if p.stat().st_size == 0:
        raise InputError("file is empty", p)
    cache = _cache_file(p)
    parts = _cache_read(cache)
    cached = parts is not None
    if not cached:
        parts = _read_parts(p)
    welded = weld(parts[0], parts[1], str(p))
    scene = _scene_of(welded, len(parts[0]), parts[2], parts[3], objects=parts[4], materials=parts[5],
                      source=str(p), warnings=tuple(f"{p}: {w}" for w in parts[6]))
    if not cached:
        _cache_write(cache, parts)  # once the weld has accepted it (finite, has faces)
    if parts[7]:
        scene = replace(scene, motion=SceneMotion.read(p, parts[7], parts, welded))
    return scene


def _read_parts(p: Path) -> tuple:
    """(vertices, faces, face_object, face_material, objects, materials, warnings, layout) of a
    mesh file, world space, through trimesh. layout: for a glTF file whose objects move
    (`moves`), each part's (glTF node, primitive, vertices, faces, mirrored) in the order of the
    arrays; () otherwise."""
    warnings: tuple[str, ...] = ()
    doc = None
    if p.suffix.lower() in (".gltf", ".glb"):
        doc = _gltf_document(p)
        _check_gltf(p, doc)
        warnings = _gltf_missing_images(p, doc)
    if p.suffix.lower() == ".stl":
        _check_stl_length(p)
    if p.suffix.lower() == ".ply":
        _check_ply(p)
    obj = _ObjStatements.of(p) if p.suffix.lower() == ".obj" else None
    if obj is not None:
        warnings = obj.warnings()
    if p.suffix.lower() == ".obj":
        warnings += short_face_warnings(p.read_bytes())
    try:
        loaded = _load_holding_interrupts(p, **(obj.load_options() if obj is not None else {}))
    except Exception as e:  # trimesh raises many kinds on bad files
        past = face_past_vertices(p.read_bytes()) if p.suffix.lower() == ".obj" else None
        raise InputError(past or f"cannot read mesh ({type(e).__name__}: {e})", p) from None
    # An OBJ split by its objects (see _ObjStatements): the pieces of one object, one per
    # material, are one object named as the OBJ names it.
    renamed = obj.object_names(loaded) if obj is not None and obj.split else {}
    obj_index: dict[str, int] = {}
    verts, faces, fobj, fmat = [], [], [], []
    objects: list[str] = []
    materials: list[Material] = []
    mat_index: dict[tuple, int] = {}
    offset = 0
    rows = []  # (trimesh node, geometry name, vertices, faces, mirrored) of each part
    for node, name in _nodes_in_stable_order(loaded):
        transform, geom_name = loaded.graph[node]
        geom = loaded.geometry[geom_name]
        f = getattr(geom, "faces", None)
        if f is None or len(f) == 0:
            continue  # point clouds and paths have no faces
        v = np.asarray(geom.vertices, np.float64)
        T = np.asarray(transform, float)
        with np.errstate(invalid="ignore", over="ignore"):  # non-finite input is reported below
            v = v @ T[:3, :3].T + T[:3, 3]
            mirrored = np.linalg.det(T[:3, :3]) < 0
        f = np.asarray(f, np.int64)
        if mirrored:
            # A mirroring node turns the winding around (glTF 2.0, node transforms: the front
            # face is then the clockwise one): facing, creases and welds come from the winding.
            f = f[:, ::-1]
        mat = _material_of(geom)
        key = (mat.name, mat.base_color)
        if key not in mat_index:
            mat_index[key] = len(materials)
            materials.append(mat)
        verts.append(v)
        faces.append(f + offset)
        if renamed:
            name = renamed.get(str(geom_name), name)
            if name not in obj_index:
                obj_index[name] = len(objects)
                objects.append(name)
            fobj.append(np.full(len(f), obj_index[name], np.int32))
        else:
            fobj.append(np.full(len(f), len(objects), np.int32))
            objects.append(name)
        fmat.append(np.full(len(f), mat_index[key], np.int32))
        rows.append((node, str(geom_name), len(v), len(f), bool(mirrored)))
        offset += len(v)
    if not faces:
        raise InputError("no triangle faces in file (empty, or a point cloud)", p)
    layout: tuple = ()
    if doc is not None and moves(doc):
        layout, why = _gltf_layout(p, loaded, rows)
        if why:
            warnings = (*warnings, f"its animation is ignored: {why}")
    return (np.concatenate(verts), np.concatenate(faces), np.concatenate(fobj), np.concatenate(fmat),
            tuple(objects), tuple(materials), warnings, layout)


class _ObjStatements:
    """What an OBJ says about its materials and objects, for what trimesh does not keep.

    - A material library (`mtllib`) that is missing: trimesh drops it in silence (every face of
      the default material, no material boundaries). It is a warning line; and when the faces use
      two or more `usemtl` names, trimesh is handed a stand-in library that declares them in the
      default colour, so the groups stay distinct materials (their boundaries are geometry the
      user may ask for). One `usemtl` name keeps the default material (no boundary to keep).
    - Objects: with two or more materials trimesh names each piece after its material ("metal",
      "wood") instead of its `o` ("crate"). An OBJ with `usemtl` and `o` lines (else `g` lines)
      is loaded split by object and each piece named after its object (object_names); pieces of
      one object are one object of the scene. Files without `usemtl` load as before."""

    def __init__(self, p: Path, text: str):
        self.path = p
        self.libraries = [n for n in _statements(text, "mtllib") if n]
        self.usemtl = list(dict.fromkeys(n for n in _statements(text, "usemtl") if n))
        self.o_names = {n for n in _statements(text, "o") if n}
        g_names = {n for n in _statements(text, "g") if n}
        self.missing = [n for n in self.libraries if not self._found(n)]
        # trimesh reads the library named after the first "mtllib" of the text, whatever the line.
        at = text.find("mtllib")
        end = text.find("\n", at)
        self.trimesh_library = text[at + 6:end if end >= 0 else len(text)].strip() if at >= 0 else None
        self.stand_in = (self.trimesh_library is not None and not self._found(self.trimesh_library)
                         and len(self.usemtl) >= 2)
        self.split = bool(self.usemtl) and bool(self.o_names or g_names)
        self.by = "o" if self.o_names else "g"
        self.names = self.o_names or g_names

    @staticmethod
    def of(p: Path) -> "_ObjStatements | None":
        """None for an OBJ with neither `mtllib` nor `usemtl` (most scanned meshes): trimesh's
        reading is all there is."""
        try:
            data = p.read_bytes()
        except OSError:
            return None  # (trimesh reports it)
        if b"mtllib" not in data and b"usemtl" not in data:
            return None
        return _ObjStatements(p, data.decode("utf-8", "replace"))

    def _found(self, name: str) -> bool:
        # as trimesh's FilePathResolver looks: the name, without a leading /, its last part
        base = self.path.parent
        return any((base / c).is_file() for c in (name.strip(), name.strip().lstrip("/"), os.path.split(name)[-1]) if c)

    def warnings(self) -> tuple[str, ...]:
        """One line per missing library, without the OBJ's name (cached by content)."""
        if self.stand_in:
            then = (f"its {len(self.usemtl)} usemtl groups are kept as materials of the default colour "
                    f"({', '.join(self.usemtl[:4])}{', ...' if len(self.usemtl) > 4 else ''})")
        else:
            then = "its material colours are lost (the faces take a default material)"
        return tuple(f"material library {n} not found beside the file: {then}" for n in self.missing)

    def load_options(self) -> dict:
        options = {}
        if self.stand_in:
            options["resolver"] = _stand_in_resolver(self.path, self.trimesh_library, self.usemtl)
        if self.split:
            options["split_objects" if self.by == "o" else "split_groups"] = True
        return options

    def object_names(self, loaded) -> dict[str, str]:
        """{geometry name: object name} of a load split by object: trimesh names a piece
        "<object>_<material>" (two or more materials in the library) or "<object>"; a piece
        before any `o` keeps trimesh's name (its material's, or the file's)."""
        out = {}
        for gname, geom in loaded.geometry.items():
            mat = getattr(getattr(getattr(geom, "visual", None), "material", None), "name", None)
            name = str(gname)
            if mat and name.endswith("_" + mat) and name[:-len(mat) - 1] in self.names:
                out[name] = name[:-len(mat) - 1]
            elif name in self.names:
                out[name] = name
        return out


def _statements(text: str, key: str) -> list[str]:
    """The arguments of the lines of an OBJ's `text` that start with statement `key`, stripped (as
    trimesh reads them: the key at the start of the line). A search for the key, not a regular
    expression over every line (about 3 times faster on a large OBJ)."""
    out: list[str] = []
    at = 0 if text.startswith(key) else text.find("\n" + key) + 1  # where a line with the key starts
    if at == 0 and not text.startswith(key):
        return out
    while True:
        end = text.find("\n", at)
        rest = text[at + len(key):end if end >= 0 else len(text)]
        if not rest or rest[0] in " \t\r":  # ("ob x" is no "o" line)
            out.append(rest.strip())
        nxt = text.find("\n" + key, end) if end >= 0 else -1
        if nxt < 0:
            return out
        at = nxt + 1


def _stand_in_resolver(p: Path, library: str, usemtl: list[str]):
    """A trimesh resolver of `p`'s folder that answers the missing material `library` with one
    that declares the `usemtl` names in the default colour (Material's 0.8 grey)."""
    from trimesh.resolvers import FilePathResolver

    text = "".join(f"newmtl {n}\nKd 0.8 0.8 0.8\n" for n in usemtl).encode()

    class StandIn(FilePathResolver):
        def get(self, name: str):
            if name.strip() == library:
                return text
            return super().get(name)

    return StandIn(str(p))


#: The bytes of a text file (tab, newlines, printable ASCII).
_TEXT_BYTES = bytes([9, 10, 13, *range(32, 127)])


def _check_stl_length(p: Path) -> None:
    """InputError for a binary STL shorter than its header says (84 bytes + 50 per triangle): cut
    off in a copy, it read as 'no triangle faces'. A file of exactly that length is binary
    whatever its header says; otherwise one whose first 4 KB are text starting with 'solid'
    (after a byte-order mark and blanks) is ASCII and left to the loader."""

    try:
        with open(p, "rb") as fh:
            head = fh.read(4096)
        size = p.stat().st_size
    except OSError:
        return
    if len(head) < 84:
        return
    (n,) = struct.unpack_from("<I", head, 80)
    if size == 84 + 50 * n:
        return
    text = head.removeprefix(b"\xef\xbb\xbf")
    if text.lstrip()[:5].lower() == b"solid" and not text.translate(None, _TEXT_BYTES):
        return  # ASCII (a binary header may start with 'solid' too, but its count and floats are not text)
    if size < 84 + 50 * n:
        raise InputError(f"truncated binary STL: its header says {n} triangles ({84 + 50 * n} bytes), the file has "
                         f"{size} bytes", p)


# --- PLY: a file cut short -------------------------------------------------------------------------

_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
              "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
              "float": "f4", "float32": "f4", "double": "f8", "float64": "f8"}
#: A PLY header longer than this is not looked at (the loader reads it).
_PLY_HEADER_MAX = 1 << 20


def _ply_rows(name: str, n: int) -> str:
    """'80 faces', '42 vertices', "3 'edge' elements" for a message."""
    return {"vertex": f"{n} vertices", "face": f"{n} faces"}.get(name, f"{n} '{name}' elements")


def _ply_row(name: str, k: int) -> str:
    return {"vertex": f"vertex {k}", "face": f"face {k}"}.get(name, f"'{name}' element {k}")


def _check_ply(p: Path) -> None:
    """InputError for a PLY file cut short, in words: a header without its end_header line, or a
    body with fewer rows (ASCII) or bytes (binary) than the header's element counts need, or
    whose last row is cut. trimesh said 'IndexError: list index out of range', 'KeyError', 'PLY is
    unexpected length!', or read an ASCII file cut in its faces without the missing faces. Files
    the check cannot size (a header of another shape) are left to the loader."""
    try:
        with open(p, "rb") as fh:
            data = fh.read()
    except OSError:
        return
    if not data.startswith(b"ply"):
        raise InputError("not a PLY file: it does not start with the line 'ply'", p)
    m = re.search(rb"^end_header[ \t]*\r?(\n|$)", data[:_PLY_HEADER_MAX], re.M)
    if m is None:
        if len(data) > _PLY_HEADER_MAX:
            return
        raise InputError("truncated PLY: the header ends before its 'end_header' line", p)
    fmt, elements = None, []  # elements: [name, count, [(kind, count dtype or None, dtype)]]
    for line in data[:m.start()].decode("latin-1").splitlines()[1:]:
        w = line.split()
        if not w or w[0] in ("comment", "obj_info"):
            continue
        try:
            if w[0] == "format":
                fmt = w[1]
            elif w[0] == "element":
                elements.append([w[1], int(w[2]), []])
            elif w[0] == "property" and w[1] == "list":
                elements[-1][2].append(("list", _PLY_TYPES[w[2]], _PLY_TYPES[w[3]]))
            elif w[0] == "property":
                elements[-1][2].append(("scalar", None, _PLY_TYPES[w[1]]))
        except (IndexError, KeyError, ValueError):
            raise InputError(f"broken PLY header: cannot read the line {line.strip()!r}", p) from None
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian") or any(n < 0 for _, n, _ in elements):
        return  # not ours to judge: the loader says what it says
    says = "its header says " + " and ".join(_ply_rows(name, n) for name, n, _ in elements if n)
    body = data[m.end():]
    where = _ply_ascii_end(body, elements) if fmt == "ascii" else \
        _ply_binary_end(body, elements, "<" if fmt == "binary_little_endian" else ">")
    if where is not None:
        raise InputError(f"truncated PLY: {says}, but the file {where}", p)


def _ply_ascii_end(body: bytes, elements: list) -> str | None:
    """Where an ASCII PLY body falls short of its elements ('ends at face 21', 'has face 80 cut
    short'), or None."""
    rows = [r for r in body.split(b"\n") if r.strip()]
    k = 0
    for name, n, props in elements:
        if k + n > len(rows):
            return f"ends at {_ply_row(name, len(rows) - k + 1)} of {n}"
        if n:
            tokens = rows[k + n - 1].split()
            need = 0
            for kind, _, _ in props:
                if kind == "scalar":
                    need += 1
                    continue
                try:
                    need += 1 + int(float(tokens[need]))
                except (IndexError, ValueError, OverflowError):  # the list's count itself is missing or no number
                    need = len(tokens) + 1
                    break
            if len(tokens) < need:
                return f"has {_ply_row(name, n)} (its last) cut short"
        k += n
    return None


def _ply_binary_end(body: bytes, elements: list, order: str) -> str | None:
    """Where a binary PLY body falls short of its elements ('ends at face 53 of 80'), or None."""
    pos = 0
    for name, n, props in elements:
        if all(kind == "scalar" for kind, _, _ in props):
            size = sum(np.dtype(t).itemsize for _, _, t in props)
            if len(body) - pos < n * size:
                return f"ends at {_ply_row(name, (len(body) - pos) // max(size, 1) + 1)} of {n}"
            pos += n * size
            continue
        if n == 0:
            continue
        # Rows of lists: every row as long as the first (a triangle mesh) is checked at once; rows
        # of mixed lengths are walked.
        first_counts, off = [], pos  # (offset in the row, count dtype, the first row's count) per list
        for kind, c, t in props:
            if kind == "scalar":
                off += np.dtype(t).itemsize
                continue
            cd = np.dtype(order + c)
            if len(body) < off + cd.itemsize:
                return f"ends at {_ply_row(name, 1)} of {n}"
            k = int(np.frombuffer(body, cd, 1, off)[0])
            first_counts.append((off - pos, cd, k))
            off += cd.itemsize + k * np.dtype(t).itemsize
        row = off - pos
        whole = min(n, (len(body) - pos) // row)
        same = all(np.all(np.ndarray((whole,), cd, body, pos + o, (row,)) == k) for o, cd, k in first_counts)
        if same and whole == n:
            pos += n * row
            continue
        if same:
            # Rows of the first row's length up to the end: the rest of them cannot fit unless
            # they are shorter; walk from there.
            start = whole
            pos += whole * row
        else:
            start = 0
        for r in range(start, n):
            for kind, c, t in props:
                size = np.dtype(t).itemsize
                if kind == "scalar":
                    pos += size
                    continue
                cd = np.dtype(order + c)
                if len(body) < pos + cd.itemsize:
                    return f"ends at {_ply_row(name, r + 1)} of {n}"
                k = int(np.frombuffer(body, cd, 1, pos)[0])
                pos += cd.itemsize + max(k, 0) * size
            if pos > len(body):
                return f"ends at {_ply_row(name, r + 1)} of {n}"
    return None


def _gltf_document(p: Path) -> dict | None:
    """The JSON document of a .gltf file, or of a .glb's JSON chunk (None where a .glb has none
    that parses: the loader reports it). A .gltf whose JSON does not parse is an InputError:
    trimesh would read it as a path to look up ("FileNotFoundError: model.gltf")."""

    try:
        data = p.read_bytes()
    except OSError:
        return None
    if p.suffix.lower() == ".gltf":
        try:
            doc = json.loads(data)
        except ValueError as e:
            raise InputError(f"not a glTF file: its JSON does not parse ({e})", p) from None
    else:
        try:
            n, kind = struct.unpack_from("<I4s", data, 12)
            doc = json.loads(data[20:20 + n]) if data[:4] == b"glTF" and kind == b"JSON" else None
        except (ValueError, struct.error):
            return None
    return doc if isinstance(doc, dict) else None


def _check_gltf(p: Path, doc: dict | None) -> None:
    """InputError for glTF triangle fans (primitive mode 6), which trimesh leaves out without a word
    (a valid file lost part of its drawing), for a cycle in the node tree and for a node rotation
    far from a unit quaternion. Points and lines (modes 0-3) have no faces to draw and are left
    out as in every format. `doc`: _gltf_document(p) (None: left to the loader)."""
    if doc is None:
        return
    meshes = doc.get("meshes", [])
    meshes = meshes if isinstance(meshes, list) else []
    fans = [(i, k) for i, m in enumerate(meshes) if isinstance(m, dict)
            for k, prim in enumerate(m.get("primitives", []) if isinstance(m.get("primitives", []), list) else [])
            if isinstance(prim, dict) and prim.get("mode") == 6]
    nodes = doc.get("nodes", [])
    nodes = nodes if isinstance(nodes, list) else []
    if fans:
        i, k = fans[0]
        raise InputError(f"mesh {i} primitive {k} is a triangle fan (mode 6), which strokekit cannot read: export "
                         "it as triangles", p)
    # The node tree: a node that is its own ancestor, or a rotation that is no rotation, was left
    # out (with its meshes) or read as something else without a word; the camera reader refuses both.
    kids = [[c for c in n.get("children", []) if isinstance(c, int) and 0 <= c < len(nodes)]
            if isinstance(n, dict) and isinstance(n.get("children", []), list) else [] for n in nodes]
    state = [0] * len(nodes)  # 0 new, 1 on the current path, 2 done
    for root in range(len(nodes)):
        stack = [(root, iter(kids[root]))] if state[root] == 0 else []
        if stack:
            state[root] = 1
        while stack:
            node, it = stack[-1]
            child = next(it, None)
            if child is None:
                state[node] = 2
                stack.pop()
            elif state[child] == 1:
                raise InputError(f"node {child} is its own ancestor (a cycle in the node tree)", p)
            elif state[child] == 0:
                state[child] = 1
                stack.append((child, iter(kids[child])))
    for i, n in enumerate(nodes):
        q = n.get("rotation") if isinstance(n, dict) else None
        if isinstance(q, list) and len(q) == 4 and all(isinstance(x, (int, float)) for x in q):
            if not (0.5 < sum(float(x) * float(x) for x in q) < 2.0):
                raise InputError(f"node {i} has rotation {q}, which is not a unit quaternion", p)
    _check_gltf_accessors(p, doc, meshes)


_GLTF_COMPONENT_BYTES = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}
_GLTF_TYPE_SIZE = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}


def _check_gltf_accessors(p: Path, doc: dict, meshes: list) -> None:
    """InputError for an accessor of a mesh primitive (attribute or indices) whose elements run
    past the end of its bufferView: trimesh said 'cannot reshape array of size 24 into shape
    (600,3)'. Matrix column padding is not counted (the need is a lower bound: no false alarm)."""
    accessors, views = doc.get("accessors"), doc.get("bufferViews")
    if not isinstance(accessors, list) or not isinstance(views, list):
        return
    used = set()
    for m in meshes:
        prims = m.get("primitives") if isinstance(m, dict) else None
        for prim in prims if isinstance(prims, list) else []:
            if not isinstance(prim, dict):
                continue
            attrs = prim.get("attributes")
            used.update(a for a in (attrs.values() if isinstance(attrs, dict) else ()) if isinstance(a, int))
            if isinstance(prim.get("indices"), int):
                used.add(prim["indices"])
    for i in sorted(used):
        a = accessors[i] if 0 <= i < len(accessors) else None
        if not isinstance(a, dict):
            continue
        v, count, offset = a.get("bufferView"), a.get("count"), a.get("byteOffset", 0)
        comp, kind = _GLTF_COMPONENT_BYTES.get(a.get("componentType")), _GLTF_TYPE_SIZE.get(a.get("type"))
        if not (isinstance(v, int) and 0 <= v < len(views) and isinstance(views[v], dict)) or comp is None \
                or kind is None or not all(isinstance(x, int) and not isinstance(x, bool) for x in (count, offset)):
            continue
        view = views[v]
        length, stride = view.get("byteLength"), view.get("byteStride") or comp * kind
        if not (isinstance(length, int) and isinstance(stride, int)) or count <= 0:
            continue
        need = offset + (count - 1) * stride + comp * kind
        if need > length:
            raise InputError(f"accessor {i} does not fit its bufferView {v}: {count} {a['type']} elements of "
                             f"{comp}-byte components from byte {offset} need {need} bytes, the view has {length}", p)


def moves(doc: dict) -> bool:
    """Whether a glTF document's objects can move or deform: it has animations, skins or morph
    targets."""
    meshes = doc.get("meshes") if isinstance(doc.get("meshes"), list) else []
    return bool(doc.get("animations") or doc.get("skins") or any(
        isinstance(prim, dict) and prim.get("targets") for m in meshes if isinstance(m, dict)
        for prim in (m.get("primitives") if isinstance(m.get("primitives"), list) else [])))


def _gltf_layout(p: Path, loaded, rows: list) -> tuple[tuple, str]:
    """(layout, "") of the parts `rows` ((trimesh node, geometry, vertices, faces, mirrored) in
    the scene's order): each part's (glTF node, primitive, vertices, faces, mirrored). The glTF
    node of a trimesh node is found by trimesh's own naming (unique_name over the node names, in
    file order); the primitive by its positions and face count. ((), reason) when a part is not
    found so (a file trimesh reads in another way): the scene then stays at rest."""
    from trimesh.util import unique_name

    g = load_gltf(p)
    data = GltfData(g, p)
    nodes = g.nodes or []
    index, counts = {}, {}
    for i, n in enumerate(nodes):
        index[unique_name(n.name if n.name else str(i), index, counts=counts)] = i
    if "world" in index:  # (trimesh renames a node that takes its base frame's name)
        index[unique_name("world", set(index))] = index.pop("world")
    parents = loaded.graph.transforms.parents
    used: set[tuple[int, int]] = set()
    layout = []
    for node, geom_name, nv, nf, mirrored in rows:
        b = index.get(str(node))
        if b is None or nodes[b].mesh is None:
            b = index.get(str(parents.get(node)))
        if b is None or nodes[b].mesh is None:
            return (), f"trimesh's node {node} is no mesh node of the file"
        geom = loaded.geometry[geom_name]
        mesh = data.item("meshes", nodes[b].mesh, f"node {b}")
        found = None
        for k, prim in enumerate(mesh.primitives or []):
            if (b, k) in used or prim.attributes.POSITION is None:
                continue
            try:
                pos = data.accessor(prim.attributes.POSITION, f"mesh {nodes[b].mesh} primitive {k} POSITION")
            except InputError:
                continue
            if pos.shape == geom.vertices.shape and np.array_equal(pos, np.asarray(geom.vertices, float)):
                found = k
                break
        if found is None:
            return (), f"no primitive of node {b}'s mesh has the positions trimesh read"
        used.add((b, found))
        layout.append((b, found, int(nv), int(nf), bool(mirrored)))
    return tuple(layout), ""


def _gltf_missing_images(p: Path, doc: dict | None) -> tuple[str, ...]:
    """Warnings (one line each, without the file's name: they are cached by content) for texture images the file refers to that are not there.
    Not an error: strokekit draws from the geometry and the material colours and never samples a
    texture, so the drawing is the same; but other tools will miss the image."""
    images = doc.get("images") if isinstance(doc, dict) else None
    missing = [(i, im["uri"]) for i, im in enumerate(images if isinstance(images, list) else [])
               if isinstance(im, dict) and isinstance(im.get("uri"), str) and im["uri"]
               and not im["uri"].startswith("data:") and not (p.parent / unquote(im["uri"])).is_file()]
    if not missing:
        return ()
    names = ", ".join(f"image {i} ({uri})" for i, uri in missing[:3]) + (", ..." if len(missing) > 3 else "")
    return (f"{names} not found beside the file: the drawing does not use textures, but other tools "
            f"will miss {'it' if len(missing) == 1 else 'them'}",)


# --- scene cache ----------------------------------------------------------------------------------
# Parsing a mesh file costs the trimesh import and the parse in every process of a run (the main
# one and each worker), and again on every run. The parsed
# arrays are kept in a cache folder under a key of the file's bytes and the versions of the
# code that read them: the same bytes give the same arrays, so outputs do not change.

#: Bump when the reading of files changes (naming, ordering, materials).
_CACHE_FORMAT = 7


def _cache_dir() -> Path | None:
    """$STROKEKIT_CACHE_DIR, else $XDG_CACHE_HOME/strokekit, else ~/.cache/strokekit;
    None when STROKEKIT_CACHE=0."""

    if os.environ.get("STROKEKIT_CACHE", "1") == "0":
        return None
    if os.environ.get("STROKEKIT_CACHE_DIR"):
        return Path(os.environ["STROKEKIT_CACHE_DIR"])
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "strokekit"


def _cache_file(p: Path) -> Path | None:
    """The cache file of mesh file `p` (None: the cache is off): named by the hash of its bytes,
    of the files it refers to (an OBJ's material libraries, a .gltf's external buffers and
    images: editing one of them is a new scene) and of the versions of the code that reads them."""
    from importlib.metadata import PackageNotFoundError, version

    folder = _cache_dir()
    if folder is None:
        return None
    try:
        stamp = f"{_CACHE_FORMAT}|{version('trimesh')}|{version('numpy')}|{p.suffix.lower()}|"
    except PackageNotFoundError:
        return None
    h = hashlib.sha256(stamp.encode())
    obj = p.suffix.lower() == ".obj"
    names: list[bytes] = []
    carry = b""
    with open(p, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
            if obj:  # mtllib lines, whole lines only (a block may end inside one)
                text = carry + block
                cut = text.rfind(b"\n") + 1
                if b"mtllib" in text[:cut]:  # (a plain search first: cheaper than the regex)
                    names += _MTLLIB.findall(text[:cut])
                carry = text[cut:]
    names += _MTLLIB.findall(carry) if obj else []
    for ref in _referenced_files(p, names):
        h.update(b"|" + str(ref.name).encode())
        try:
            h.update(hashlib.sha256(ref.read_bytes()).digest())
        except OSError:
            h.update(b"(missing)")
    return folder / "scenes" / f"{h.hexdigest()}.npz"


_MTLLIB = re.compile(rb"^[ \t]*mtllib[ \t]+([^\r\n]*?)[ \t]*\r?$", re.M)


def _referenced_files(p: Path, mtllib: list[bytes]) -> list[Path]:
    """The files that mesh file `p` refers to and trimesh reads with it: the material libraries of
    an OBJ (`mtllib` lines), the external buffers and images of a .gltf or .glb."""
    if p.suffix.lower() == ".obj":
        return [p.parent / n.decode("utf-8", "replace") for n in mtllib if n]
    if p.suffix.lower() not in (".gltf", ".glb"):
        return []
    try:
        doc = _gltf_document(p)
        uris = [x.get("uri") for key in ("buffers", "images") for x in doc.get(key) or [] if isinstance(x, dict)]
    except (InputError, ValueError, AttributeError, TypeError):
        return []  # not parsed here: the load reports it
    return [p.parent / unquote(u) for u in uris if isinstance(u, str) and u and not u.startswith("data:")]


def _cache_read(f: Path | None) -> tuple | None:
    if f is None:
        return None
    try:
        with np.load(f, allow_pickle=False) as z:
            objects = tuple(json.loads(str(z["objects"])))
            materials = tuple(Material(m[0], tuple(m[1])) for m in json.loads(str(z["materials"])))
            warnings = tuple(str(w) for w in json.loads(str(z["warnings"])))
            layout = tuple(tuple(r) for r in json.loads(str(z["layout"])))
            return (z["vertices"], z["faces"], z["face_object"], z["face_material"], objects, materials, warnings,
                    layout)
    except Exception:  # absent, unreadable, truncated (BadZipFile, EOFError, zlib.error) or from
        return None  # another layout: a cache never breaks a load, the file is read again


def _cache_write(f: Path | None, parts: tuple) -> None:
    if f is None:
        return

    buf = io.BytesIO()
    np.savez(buf, vertices=parts[0], faces=parts[1], face_object=parts[2], face_material=parts[3],
             objects=np.array(json.dumps(list(parts[4]))),
             materials=np.array(json.dumps([[m.name, list(m.base_color)] for m in parts[5]])),
             warnings=np.array(json.dumps(list(parts[6]))), layout=np.array(json.dumps([list(r) for r in parts[7]])))
    try:
        atomic_write_bytes(f, buf.getvalue())
    except OSError:  # a read-only home or a full disk only costs the next run its parse time
        pass


def _object_name(node: str, geometry: str, parent: str | None) -> str:
    """The name of a scene object: its glTF node's name, or its mesh's name where trimesh made the
    node name up. trimesh names a node without a name by its index, and gives each primitive of a
    multi-primitive mesh a child node "<parent>_<6 random hex digits>", new on every load: such a
    name must neither name the object nor order the faces."""
    made_up = node.isdigit() or (parent is not None and re.fullmatch(re.escape(parent) + r"_[0-9a-f]{6}", node))
    return geometry if made_up else node


def _nodes_in_stable_order(loaded) -> list[tuple]:
    """(node, object name) of the geometry nodes of a trimesh scene, in an order that is the same
    on every load: by object name, mesh name (deterministic) and world transform. Face order,
    object ids and the scene hash follow from it."""
    parents = loaded.graph.transforms.parents
    rows = []
    for node in loaded.graph.nodes_geometry:
        transform, geom_name = loaded.graph[node]
        parent = parents.get(node)
        name = _object_name(str(node), str(geom_name), None if parent is None else str(parent))
        rows.append(((name, str(geom_name), np.asarray(transform, np.float64).tobytes()), node, name))
    rows.sort(key=lambda r: r[0])
    return [(node, name) for _, node, name in rows]


def _load_holding_interrupts(path: Path, **options):
    """Import trimesh and load `path` with Ctrl-C held until done (hold_interrupts: trimesh
    catches BaseException around its optional imports and between loaders). `options`: the
    OBJ loader's (resolver, split_objects, split_groups)."""
    with hold_interrupts():
        import trimesh

        return trimesh.load(str(path), force="scene", process=False, **options)
