"""Scenes that move: glTF node animation, skins and morph targets posed on the CPU, each frame the
scene a static file of its posed vertices would give, drawn as that scene is drawn; the objects'
surface points carried with them from frame to frame. The animated files are made here
(tests/animated.py) or are the CesiumMilkTruck's own animation (its two wheels turning)."""

from __future__ import annotations

import json
import math

import numpy as np
import pygltflib
import pytest
from animated import (
    Doc,
    skinned_tube_glb,
    skinned_tube_vertices,
    sphere_and_box_glb,
    turntable_glb,
    yaw_matrix,
)
from helpers import model_path, run_cli
from scipy.spatial.transform import Rotation, Slerp

from strokekit.camera.paths import orbit_path
from strokekit.camera.view import Camera
from strokekit.errors import InputError
from strokekit.lines.renderer import LineRenderer
from strokekit.metrics.accuracy import frame_accuracy
from strokekit.model import Strokes, carry_points
from strokekit.options import LineOptions
from strokekit.run.request import RenderRequest
from strokekit.run.sequence import render_sequence
from strokekit.scene.load import build_scene, load_scene
from strokekit.writers.svg import svg_document

TRUCK = "CesiumMilkTruck.glb"


def static_of(scene, t: float, animation: int = 0):
    """The static scene a file of the scene's posed vertices at time t gives (no motion)."""
    m = scene.motion
    return build_scene(m.file_vertices_at(animation, t), m.file_faces, m.file_face_object, m.file_face_material,
                       objects=scene.objects, materials=scene.materials, source=scene.source)


def svg(strokes: Strokes, options: LineOptions) -> str:
    cam = strokes.camera
    return svg_document(strokes, cam.width, cam.height, options.layers)


@pytest.fixture(scope="module")
def truck():
    return load_scene(model_path(TRUCK))


@pytest.fixture(scope="module")
def tube_file(tmp_path_factory):
    return skinned_tube_glb(tmp_path_factory.mktemp("tube") / "tube.glb")


# --- posing ----------------------------------------------------------------------------------------

def test_the_truck_wheels_turn_as_their_keys_say(truck):
    """The wheels' rows are the wheel mesh turned by the rotation slerped between the file's keys
    (scipy's Slerp here) under the wheel node's parent matrix; the body's rows stay at rest."""
    g = pygltflib.GLTF2().load(str(model_path(TRUCK)))
    m = truck.motion
    anim = g.animations[0]
    moved = 0
    for t in (0.1, 0.55, 1.2):
        V = m.file_vertices_at(0, t)
        for k, part in enumerate(m.parts):
            rows = V[part.vertices]
            ch = [c for c in anim.channels if c.target.node == part.node]
            if not ch:
                assert m.kind(0, k) == "static"
                assert np.array_equal(rows, m.file_vertices[part.vertices])
                continue
            smp = anim.samplers[ch[0].sampler]
            from strokekit.animation import GltfData

            data = GltfData(g, model_path(TRUCK))
            keys, quats = data.accessor(smp.input, "keys")[:, 0], data.accessor(smp.output, "values")
            R = Slerp(keys, Rotation.from_quat(quats))([t]).as_matrix()[0]
            parent = next(i for i, n in enumerate(g.nodes) if part.node in (n.children or []))
            P = np.array(g.nodes[parent].matrix, float).reshape(4, 4).T
            want = part.mesh_vertices @ (P[:3, :3] @ R).T + P[:3, 3]
            assert np.allclose(rows, want, atol=1e-9)
            moved += 1
    assert moved == 6


def test_a_skinned_tube_bends_as_its_joints_say(tube_file):
    """Linear blend skinning of the tube's two joints, as computed here from the known bend."""
    s = load_scene(tube_file)
    for t in (0.0, 0.3, 0.75, 1.5):
        assert np.allclose(s.motion.file_vertices_at(0, t), skinned_tube_vertices(t), atol=1e-6)
    assert np.abs(s.motion.file_vertices_at(0, 1.0) - s.motion.file_vertices_at(0, 0.0)).max() > 0.5


@pytest.mark.parametrize("which", ["truck", "tube", "box"])
def test_a_posed_scene_is_the_static_scene_of_its_posed_vertices(which, truck, tube_file, tmp_path):
    """Same vertices (welded, in the weld's order), faces, objects, materials, topology and face
    tables as a scene built from the posed vertices: where most vertices move (the truck's wheels,
    the tube) and where a few do (a box turning beside a still sphere: their rows merged into the
    still ones' order)."""
    scene = {"truck": lambda: truck, "tube": lambda: load_scene(tube_file),
             "box": lambda: load_scene(sphere_and_box_glb(tmp_path / "box.glb", "box"))}[which]()
    for t in (0.0, 0.1, 0.3, 0.4, 0.9, 2.0):
        posed, ref = scene.at(t, 0), static_of(scene, t)
        for name in ("vertices", "faces", "face_object", "face_material"):
            assert np.array_equal(getattr(posed, name), getattr(ref, name)), name
        for a, b in zip(posed._topology, ref._topology):
            assert np.array_equal(a, b)
        for table in ("face_normals", "face_offsets", "dihedral_cos"):  # (carried where no face moved)
            assert np.array_equal(getattr(posed, table), getattr(ref, table)), table
        assert posed.content_hash == ref.content_hash


def test_renumbered_edges_merged_into_the_still_ones_sort_as_the_topology_sorts(tmp_path):
    """A box turning beside a still sphere: its few edges sorted and merged into the still ones'
    order are the edges of a sort of them all (and the static scene's), with the same faces; the
    carried manifold face pairs are the rebuilt ones."""
    from strokekit.scene.motion import _renumbered_topology

    s = load_scene(sphere_and_box_glb(tmp_path / "box.glb", "box"))
    _ = s.manifold_face_pairs
    moving = s.motion._moving_edges(s, 0)
    assert 0 < moving[0].sum() * 8 < len(s.edges)  # (the merge, not the sort of all)
    for t in (0.1, 0.4):
        posed, ref = s.at(t, 0), static_of(s, t)
        # The renumbering: each rest vertex's row among the posed scene's (by its position).
        P = s.motion.file_vertices_at(0, t)[s.motion._kinds["rest weld"][0]]
        order = np.lexsort((P[:, 2], P[:, 1], P[:, 0]))
        new = np.empty(len(order), np.int64)
        new[order] = np.arange(len(order))
        merged, _ = _renumbered_topology(s, new, moving)
        whole, _ = _renumbered_topology(s, new)
        for a, b, c in zip(merged, whole, ref._topology):
            assert np.array_equal(a, b) and np.array_equal(a, c)
        for a, b in zip(posed.manifold_face_pairs, ref.manifold_face_pairs):
            assert np.array_equal(a, b)


def test_two_animations_moving_different_objects_pose_each_as_its_static_scene(tmp_path):
    """What the posing keeps of one animation's moving objects (their rows, edges and faces) is
    that animation's: the sphere turned by one and the box by the other, in turns, each frame is
    the static scene of its posed vertices."""
    import trimesh

    sph = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    box = trimesh.creation.box(extents=(0.8, 0.8, 0.8))
    d = Doc()
    a = d.node(mesh=d.mesh(np.asarray(sph.vertices), np.asarray(sph.faces)), name="sphere")
    b = d.node(mesh=d.mesh(np.asarray(box.vertices), np.asarray(box.faces)), name="box", translation=[0.2, 1.55, 0.3])
    k = np.arange(13)
    for node in (b, a):
        d.animate([(node, "rotation", k / 24, [[0.0, math.sin(math.radians(5 * i)), 0.0, math.cos(math.radians(5 * i))]
                                               for i in k])])
    s = load_scene(d.save(tmp_path / "two.glb"))
    for t, ai in ((0.1, 0), (0.2, 1), (0.3, 0), (0.4, 1)):
        posed, ref = s.at(t, ai), static_of(s, t, ai)
        assert np.array_equal(posed.vertices, ref.vertices) and np.array_equal(posed.faces, ref.faces)
        for x, y in zip(posed._topology, ref._topology):
            assert np.array_equal(x, y)
        for table in ("face_normals", "face_offsets", "dihedral_cos"):
            assert np.array_equal(getattr(posed, table), getattr(ref, table)), table


def test_rows_sorted_by_x_alone_where_x_is_unique_sort_as_lexsort():
    """_lex_order sorts by x alone where no two rows share it, and by x, y, z otherwise: either
    way np.lexsort's order (-0.0 and 0.0 count as the same x)."""
    from strokekit.scene.motion import _lex_order
    rng = np.random.default_rng(2)
    for k in range(60):
        P = rng.normal(size=(300, 3))
        if k % 3 == 1:
            P[:, 0] = np.round(P[:, 0], 1)  # shared x
        if k % 3 == 2:
            P[:150, 0], P[150:, 0] = 0.0, -0.0
        want = np.lexsort((P[:, 2], P[:, 1], P[:, 0]))
        memo: dict = {}
        assert np.array_equal(_lex_order(P), want) and np.array_equal(_lex_order(P, memo), want)
        assert np.array_equal(_lex_order(P, memo), want)  # (with what the first call remembered)


def test_moving_rows_merged_into_the_still_ones_sort_as_the_weld_sorts():
    """Rows sharing x (and y) with still rows are placed by y, then z; a moving row landing on a
    still one is a meeting of welded vertices (None)."""
    from strokekit.scene.motion import _sorted_order
    rng = np.random.default_rng(0)
    for _ in range(100):
        P = np.unique(rng.integers(0, 6, (200, 3)).astype(float), axis=0)
        rng.shuffle(P)
        moved = np.zeros(len(P), bool)
        moved[rng.choice(len(P), size=len(P) // 10, replace=False)] = True
        still = np.flatnonzero(~moved)
        still = still[np.lexsort((P[still, 2], P[still, 1], P[still, 0]))]
        order = _sorted_order(P, still, np.flatnonzero(moved))
        assert np.array_equal(order, np.lexsort((P[:, 2], P[:, 1], P[:, 0])))
        P[np.flatnonzero(moved)[0]] = P[still[0]]
        assert _sorted_order(P, still, np.flatnonzero(moved)) is None


# --- lines of posed frames -------------------------------------------------------------------------

def test_posed_truck_frames_draw_the_static_scenes_lines_byte_for_byte(truck):
    """Every frame of the wheels' turn, from four sides: the SVG of the posed frame is the SVG of a
    static scene of its posed vertices, and its lines are those within 1 px of the exact preset's
    (P and R >= 0.999)."""
    opts, exact = LineOptions(), LineOptions.preset("exact")
    base = LineRenderer(truck, opts)
    cams = orbit_path(*truck.framing()[:2], 4).cameras
    for k in range(0, 31, 5):
        t, cam = k / 24, cams[k % 4]
        drawn = base.at(t).render(cam, k + 1)
        ref = static_of(truck, t)
        assert svg(drawn, opts) == svg(LineRenderer(ref, opts).render(cam, k + 1), opts)
        if k % 10 == 0:
            acc = frame_accuracy(drawn, LineRenderer(ref, exact).render(cam, k + 1), tols=(1.0,))
            assert acc.precision[1.0] >= 0.999 and acc.recall[1.0] >= 0.999


def test_posed_truck_frames_rasterize_and_hide_as_the_static_scene(truck):
    """Hidden lines and the raster pass (the EXR passes' and toon bands' samples) of a posed
    frame are the static scene's of its posed vertices, not the rest scene's."""
    from strokekit.raster.bands import RasterOptions

    cam = orbit_path(*truck.framing()[:2], 8, elevation=25).cameras[1]
    request = RenderRequest(lines=LineOptions(occlusion=(0, 3)), raster=RasterOptions())
    for k in (1, 9, 17):
        a = next(render_sequence(truck, [(k, cam)], request))
        b, rest = (next(render_sequence(static_of(truck, t), [(k, cam)], request)) for t in ((k - 1) / 24, 0.0))
        assert svg_document(a.strokes, 1024, 1024, a.layers) == svg_document(b.strokes, 1024, 1024, b.layers)
        assert "hidden-" in svg_document(a.strokes, 1024, 1024, a.layers)
        for name in ("face", "bary", "depth"):
            assert np.array_equal(getattr(a.raster.hits, name), getattr(b.raster.hits, name)), name
        assert np.array_equal(a.raster.labels_ss, b.raster.labels_ss)
        assert k == 1 or not np.array_equal(a.raster.hits.depth, rest.raster.hits.depth)  # (the wheels turned)


def test_posed_tube_frames_draw_the_static_scenes_lines_byte_for_byte(tube_file):
    s = load_scene(tube_file)
    opts, exact = LineOptions(), LineOptions.preset("exact")
    base = LineRenderer(s, opts)
    cam = orbit_path(*s.framing()[:2], 1).cameras[0]
    for k in (0, 6, 12, 24):
        t = k / 24
        drawn = base.at(t).render(cam, k + 1)
        ref = static_of(s, t)
        assert svg(drawn, opts) == svg(LineRenderer(ref, opts).render(cam, k + 1), opts)
        acc = frame_accuracy(drawn, LineRenderer(ref, exact).render(cam, k + 1), tols=(1.0,))
        assert acc.precision[1.0] >= 0.999 and acc.recall[1.0] >= 0.999
    # the bend moves the drawing
    assert svg(base.at(0.0).render(cam), opts) != svg(base.at(1.0).render(cam), opts)


# --- a turntable is an orbit ---------------------------------------------------------------------

def spot_turntable(tmp_path, frames: int):
    spot = load_scene(model_path("spot.obj"))
    V = spot.vertices - spot.center
    return (turntable_glb(tmp_path / "turn.glb", V, spot.faces, frames=frames),
            turntable_glb(tmp_path / "still.glb", V, spot.faces, frames=frames, animated=False))


def relative_orbit(still_camera: Camera, frames: int, deg_per_frame: float = 3.0) -> list[Camera]:
    """The cameras that see the still object as the still camera sees it turned by deg_per_frame
    a frame about +Y through the origin."""
    out = []
    for k in range(frames):
        R = yaw_matrix(deg_per_frame * k).T
        out.append(Camera(eye=tuple(R @ np.asarray(still_camera.eye)), target=tuple(R @ np.asarray(still_camera.target)),
                          up=tuple(R @ np.asarray(still_camera.up)), fov_y=still_camera.fov_y,
                          width=still_camera.width, height=still_camera.height))
    return out


def test_a_turntable_draws_what_the_orbit_of_the_same_relative_motion_draws(tmp_path):
    """The object turned 3 degrees a frame before a still camera, and the still object seen from
    the cameras of the same relative motion: every frame's lines within 0.05 px (P and R >=
    0.999)."""
    frames = 16
    turn, still = spot_turntable(tmp_path, frames)
    s = load_scene(turn)
    cam = orbit_path(*s.framing()[:2], 1, elevation=20.0).cameras[0]
    request = RenderRequest(strokes="lines", coherence="none")
    a = [f.lines for f in render_sequence(turn, [cam] * frames, request)]
    b = [f.lines for f in render_sequence(still, relative_orbit(cam, frames), request)]
    for x, y in zip(a, b):
        acc = frame_accuracy(x, y, tols=(0.05,))
        assert acc.precision[0.05] >= 0.999 and acc.recall[0.05] >= 0.999
    assert svg(a[0], request.lines) != svg(a[5], request.lines)


def test_points_carried_with_a_turning_object_land_on_it_again(tmp_path):
    """A frame's surface points carried to the next frame are the points turned by the frame's
    3 degrees; carried back they are where they were."""
    turn, _ = spot_turntable(tmp_path, 4)
    s = load_scene(turn)
    a, b = s.at(0.0, 0), s.at(1 / 24, 0)
    face = np.arange(0, len(a.faces), 97)
    X = a.vertices[a.faces[face]].mean(axis=1)
    Y = carry_points(X, face, a.pose, b.pose)
    assert np.allclose(Y, X @ yaw_matrix(3.0).T, atol=1e-6)
    assert np.allclose(carry_points(Y, face, b.pose, a.pose), X, atol=1e-9)


# --- the frame JSON ----------------------------------------------------------------------------------

def test_a_moving_scenes_frame_json_gives_each_points_object_and_its_point_there(tmp_path, truck):
    frames = list(render_sequence(model_path(TRUCK), [orbit_path(*truck.framing()[:2], 1).cameras[0]] * 3,
                                  RenderRequest(strokes="lines", coherence="none")))
    d = json.loads(frames[2].to_json())
    assert d["time"] == pytest.approx(2 / 24) and len(d["objects"]) == len(truck.objects)
    M = np.array([o["matrix"] for o in d["objects"]])
    for st in d["strokes"]:
        obj, local, X = np.array(st["object"]), np.array(st["local"]), np.array(st["surface"])
        assert (obj >= 0).all()
        back = np.einsum("nij,nj->ni", M[obj][:, :3, :3], local) + M[obj][:, :3, 3]
        assert np.allclose(back, X, atol=1e-6)


def test_a_still_scenes_frame_json_has_no_pose(tmp_path):
    spot = load_scene(model_path("spot.obj"))
    f = next(render_sequence(spot, orbit_path(spot.center, spot.radius, 1)))
    d = json.loads(f.to_json())
    assert "time" not in d and "objects" not in d and "local" not in d["strokes"][0]


# --- info, framing, bad input ----------------------------------------------------------------------

def test_info_lists_the_animations_and_their_length(capsys):
    code, out, _ = run_cli(["info", model_path(TRUCK)], capsys)
    assert code == 0 and "animations  0: 1.25 s" in out
    code, out, _ = run_cli(["info", model_path(TRUCK), "--json"], capsys)
    assert json.loads(out)["animations"] == [{"index": 0, "name": "", "start": 0.0, "end": 1.25, "seconds": 1.25,
                                              "moves": True}]


def test_camera_orbit_frames_the_scene_over_the_whole_animation(tmp_path, capsys):
    """A box that slides 10 units away: the orbit keeps both ends of its way in view."""
    d = Doc()
    box = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    tris = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                     [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    n = d.node(mesh=d.mesh(box, tris))
    d.animate([(n, "translation", [0.0, 2.0], [[0, 0, 0], [10, 0, 0]])])
    p = d.save(tmp_path / "slide.glb")
    code, out, _ = run_cli(["camera", "orbit", p, "--frames", "1"], capsys)
    assert code == 0
    c = Camera.from_json({**json.loads(out)["frames"][0], "width": 1024, "height": 1024})
    for x in (-1.0, 11.0):
        q, _ = c.project(np.array([[x, 0.0, 0.0]]))
        assert 0 < q[0, 0] < 1024 and 0 < q[0, 1] < 1024
    s = load_scene(p)
    assert s.framing()[1] > 5.0 > s.radius


def _broken(tmp_path, how: str):
    d = Doc()
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    n = d.node(mesh=d.mesh(V, [[0, 1, 2]]))
    d.animate([(n, "translation", [0.0, 1.0], [[0, 0, 0], [1, 0, 0]])], name="slide")
    g = d.g
    if how == "missing node":
        g.animations[0].channels[0].target.node = 7
    elif how == "counts":
        g.accessors[g.animations[0].samplers[0].input].count = 1
    elif how == "nan":
        d.animate([(n, "translation", [0.0, float("nan")], [[0, 0, 0], [1, 0, 0]])], name="bad")
        g.animations.pop(0)
    elif how == "order":
        d.animate([(n, "translation", [1.0, 0.5], [[0, 0, 0], [1, 0, 0]])], name="bad")
        g.animations.pop(0)
    elif how == "joints":
        j = d.node(name="joint")
        g.scenes[0].nodes.remove(j)  # a joint outside the scene
        g.skins.append(pygltflib.Skin(joints=[j]))
        g.nodes[n].skin = 0
    return d.save(tmp_path / f"{how.replace(' ', '_')}.glb")


@pytest.mark.parametrize("how,needle", [("missing node", "targets node 7, which does not exist"),
                                        ("counts", "needs 1 VEC3 values for 1 LINEAR keys, got 2"),
                                        ("nan", "sampler 0 input: accessor 4 holds non-finite values"),
                                        ("order", "sampler 0: key times must increase strictly"),
                                        ("joints", "joint node 1 is not in the scene")])
def test_a_broken_animation_is_one_line_naming_the_file_and_the_animation(tmp_path, capsys, how, needle):
    p = _broken(tmp_path, how)
    with pytest.raises(InputError) as e:
        load_scene(p)
    msg = str(e.value)
    assert needle in msg and str(p) in msg and "\n" not in msg
    if how != "joints":  # (a skin is no animation's: the message names the skin)
        assert ("animation 0 ('slide')" if how in ("missing node", "counts") else "animation 0 ('bad')") in msg
    code, _, err = run_cli(["render", p, "--orbit", "2", "--out", tmp_path / "out", "-q"], capsys)
    assert code == 1 and needle in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "out" / "frame_0001.svg").exists()


def test_an_unknown_animation_name_is_one_clear_error(tmp_path, capsys, truck):
    code, _, err = run_cli(["render", model_path(TRUCK), "--orbit", "2", "--animation", "walk", "--out",
                            tmp_path / "o", "-q"], capsys)
    assert code == 1 and "has no animation 'walk' (it has 0)" in err


def test_time_offset_moves_the_frames_along_the_animation(tmp_path, truck):
    cam = orbit_path(*truck.framing()[:2], 1).cameras[0]
    late = next(render_sequence(truck, [cam], RenderRequest(strokes="lines", time_offset=0.5)))
    shifted = list(render_sequence(truck, [cam] * 13, RenderRequest(strokes="lines", coherence="none")))[12]
    assert late.time == shifted.time == pytest.approx(0.5)
    assert np.array_equal(late.lines.points, shifted.lines.points)
    assert math.isclose(json.loads(late.to_json())["time"], 0.5)


# --- objects that keep their BVH ---------------------------------------------------------------------

@pytest.mark.parametrize("moving", ["sphere", "box"])
def test_kept_bvhs_answer_as_the_posed_scenes_own(tmp_path, moving):
    """The frame's occluder of kept and rebuilt BVHs (rays taken into each one's frame) meets what
    the posed scene's own BVH meets: the same first faces, occlusions and crossings for all but
    the rays that graze an edge, t within float32 rounding (but where a ray grazes its face,
    which amplifies it), and lines within 0.05 px of the static scene's."""
    from strokekit.scene.occluder import Occluder, PosedRays

    s = load_scene(sphere_and_box_glb(tmp_path / f"{moving}.glb", moving))
    rays_of = PosedRays(s, 0)
    assert not rays_of.whole and len(rays_of.groups) == 2
    rng = np.random.default_rng(1)
    for t in (0.1, 0.4):
        posed = s.at(t, 0)
        kept, own = rays_of.occluder(posed), Occluder(posed)
        assert kept.parts is not None and own.parts is None
        o = rng.normal(size=(4000, 3)) * 3.0
        d = posed.vertices[posed.faces[rng.integers(0, len(posed.faces), 4000)]].mean(axis=1) - o  # face centres
        a, b = kept.first_hits(o, d), own.first_hits(o, d)
        same = a["primitive_ids"] == b["primitive_ids"]
        assert same.mean() > 0.995
        hit = same & (a["primitive_ids"] >= 0)
        assert np.quantile(np.abs(a["t_hit"][hit] - b["t_hit"][hit]) / b["t_hit"][hit], 0.99) < 1e-5
        assert (kept.occluded_segments(o, o + 0.9 * d) == own.occluded_segments(o, o + 0.9 * d)).mean() > 0.995
        assert (kept.crossings(o, d) == own.crossings(o, d)).mean() > 0.99
        cam = orbit_path(*s.framing()[:2], 1, elevation=25.0).cameras[0]
        drawn = LineRenderer(s, LineOptions()).at(t).render(cam)
        ref = LineRenderer(static_of(s, t), LineOptions()).render(cam)
        acc = frame_accuracy(drawn, ref, tols=(0.05,))
        assert acc.precision[0.05] >= 0.999 and acc.recall[0.05] >= 0.999


@pytest.mark.parametrize("request_", [RenderRequest(), RenderRequest(strokes="lines", coherence="kalnins")],
                         ids=["brush paths", "tracked lines"])
def test_strokes_follow_a_turning_object_as_they_follow_the_orbit(tmp_path, request_):
    """The tracker and the brush paths carry ids and u with the turning object: M1 of the
    turntable's strokes (the metrics carry the points with the object too) within 0.005 of the
    orbit's, and its paths' wholeness (M8) within 0.005 of the orbit's. Without the points carried
    (a still scene's correspondence) the turntable's silhouettes would slide 3 degrees a frame
    under their votes."""
    from strokekit.metrics.coherence import sequence_metrics, wholeness

    frames = 24
    turn, still = spot_turntable(tmp_path, frames)
    s = load_scene(turn)
    cam = orbit_path(*s.framing()[:2], 1, elevation=20.0).cameras[0]
    a = [f.strokes for f in render_sequence(turn, [cam] * frames, request_)]
    b = [f.strokes for f in render_sequence(still, relative_orbit(cam, frames), request_)]
    ma, mb = sequence_metrics(a)[1], sequence_metrics(b)[1]
    assert mb["M1"] > 0.9 and abs(ma["M1"] - mb["M1"]) <= 0.005
    assert abs(ma["M4_median"] - mb["M4_median"]) <= 0.05
    if request_.strokes is None:
        fresh = RenderRequest(strokes="brush", coherence="none")
        fa = [f.strokes for f in render_sequence(turn, [cam] * frames, fresh)]
        fb = [f.strokes for f in render_sequence(still, relative_orbit(cam, frames), fresh)]
        wa, wb = wholeness(a, fa)[1], wholeness(b, fb)[1]
        assert abs(wa["M8"] - wb["M8"]) <= 0.005 and abs(wa["M8_ratio"] - wb["M8_ratio"]) <= 0.005


def test_coherence_moves_a_deforming_objects_points_with_the_scene(tmp_path, capsys, tube_file):
    """From the frame JSON alone the bending tube's points stay where they were (its object
    deforms: its local points are in the mesh's bind pose); with --scene they move with the
    mesh, and every previous sample finds its match again (M2 near 0)."""
    cam = tmp_path / "still.json"
    assert run_cli(["camera", "orbit", tube_file, "--frames", "13", "--degrees-per-frame", "0", "-o", cam], capsys)[0] == 0
    out = tmp_path / "out"
    assert run_cli(["render", tube_file, "--camera", cam, "--out", out, "-q"], capsys)[0] == 0
    _, plain, _ = run_cli(["coherence", out, "--json"], capsys)
    _, posed, _ = run_cli(["coherence", out, "--json", "--scene", tube_file], capsys)
    plain, posed = json.loads(plain)["overall"], json.loads(posed)["overall"]
    assert posed["M2_median"] < 0.01 < plain["M2_median"]
    assert posed["M1"] >= plain["M1"]
    code, _, err = run_cli(["coherence", out, "--scene", model_path("spot.obj")], capsys)
    assert code == 1 and "not a moving scene" in err


def test_threads_pose_a_fresh_scene_at_once():
    """Frames drawn by threads pose one scene at the same time: its lazily made tables must be
    whole whenever another thread sees them (a half-made entry failed a frame with KeyError)."""
    import sys

    switch = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)  # (threads switch as often as they can: a race shows)
    try:
        _pose_in_threads()
    finally:
        sys.setswitchinterval(switch)


def _pose_in_threads():
    from concurrent.futures import ThreadPoolExecutor

    for _ in range(6):
        s = load_scene(model_path(TRUCK))
        with ThreadPoolExecutor(4) as pool:
            posed = list(pool.map(s.at, [0.1, 0.4, 0.7, 1.0] * 2))
        alone = load_scene(model_path(TRUCK))
        for t, p in zip([0.1, 0.4, 0.7, 1.0], posed):
            q = alone.at(t)
            assert np.array_equal(p.vertices, q.vertices) and np.array_equal(p.faces, q.faces)
