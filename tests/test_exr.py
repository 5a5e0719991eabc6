"""Compositing passes (issue 18): the multilayer EXR with depth, normals, shade, bands, Cryptomatte and
lines; the lines raster; PNG colour-space chunks; pass file names that compositors read as sequences."""

from __future__ import annotations

import io
import json
import re
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from strokekit.cryptomatte import (
    RankedMatte,
    header_attributes,
    layer_key,
    manifest_json,
    murmur3_32,
    murmur3_32_py,
    name_to_bits,
    name_to_hex,
    name_to_id,
    rank_coverage,
    rank_samples,
    ranked_matte,
)
from strokekit.model import BACKGROUND_DEPTH
from strokekit.options import QUALITY_PRESETS
from strokekit.writers.exr import openexr_file, read_exr
from strokekit_cli.main import main

SAMPLE = Path(__file__).resolve().parents[1] / "samples" / "still_life.glb"
OBJECTS = ("ball", "box", "ground", "ring", "vase")


def render(tmp_path: Path, *args, out: str = "out") -> Path:
    with pytest.raises(SystemExit) as e:
        main([str(a) for a in ["render", SAMPLE, "--orbit", "2", "--frames", "1", "-q", "--out", tmp_path / out,
                               *args]])
    assert e.value.code == 0
    return tmp_path / out


# --- Cryptomatte ids: the specification's values --------------------------------------------------

def test_cryptomatte_ids_are_the_specifications():
    """The manifest values of the specification's examples (Psyop, Cryptomatte 1.1.0), the layer
    key of "CryptoObject" as Blender writes it, and ids that are never NaN, inf or denormal."""
    assert name_to_hex("bunny") == "13851a76"
    assert name_to_hex("default") == "42c9679f"
    assert name_to_hex("bunny_porcelain_mat") == "b24b26d4"
    assert layer_key("CryptoObject") == "3ae39a5"
    for n in ("bunny", "", "a" * 100, "ümlaut", "box"):
        bits = name_to_bits(n)
        assert 1 <= (bits >> 23) & 0xFF <= 254, n
        assert np.isfinite(name_to_id(n))
    assert json.loads(manifest_json(["b", "a"])) == {"a": name_to_hex("a"), "b": name_to_hex("b")}
    h = header_attributes("CryptoObject", ["box"])
    assert h == {"cryptomatte/3ae39a5/name": "CryptoObject", "cryptomatte/3ae39a5/hash": "MurmurHash3_32",
                 "cryptomatte/3ae39a5/conversion": "uint32_to_float32",
                 "cryptomatte/3ae39a5/manifest": '{"box":"%s"}' % name_to_hex("box")}


def test_the_pure_python_hash_is_murmur3():
    """The fallback when mmh3 is missing hashes as mmh3 does: every tail length (0 to 3 bytes
    after the 4-byte blocks), other seeds, non-ASCII names, and the specification's values."""
    mmh3 = pytest.importorskip("mmh3")
    rng = np.random.default_rng(7)
    for n in range(0, 41):
        data = rng.integers(0, 256, n, dtype=np.uint8).tobytes()
        for seed in (0, 1, 0x9747B28C, 0xFFFFFFFF):
            assert murmur3_32_py(data, seed) == mmh3.hash(data, seed, signed=False), (n, seed)
    assert murmur3_32_py("ümlaut".encode()) == murmur3_32("ümlaut")
    assert murmur3_32_py(b"") == 0 and murmur3_32_py(b"", 1) == 0x514E28B7


def test_cryptomatte_rank_0_holds_the_highest_coverage():
    """The specification ranks the ids of a pixel by coverage, highest first (compositors read rank
    0 first, and a keyer that stops early keeps the main object); equal coverages go by ascending
    id bits; unused ranks hold id 0 and coverage 0. Checked on per-sample ranking, on per-name
    coverage maps and on a raster pass whose edge pixels have samples of their own."""
    names = ["ball", "box", "vase"]
    ball, box, vase = (np.float32(name_to_id(n)) for n in names)
    low, high = sorted((ball, box), key=lambda x: int(x.view(np.uint32)))
    # pixel 0: ball 3 of 4 samples, box 1; pixel 1: box 2, vase 1, background 1; pixel 2: a tie
    samples = np.array([[[0, 1, 0, 0], [1, -1, 2, 1], [1, 0, 0, 1]]])
    m = rank_samples(samples, names, ranks=4)
    assert m.ids[0, 0].tolist() == [ball, box, 0, 0] and m.coverage[0, 0].tolist() == [0.75, 0.25, 0, 0]
    assert m.ids[0, 1].tolist() == [box, vase, 0, 0] and m.coverage[0, 1].tolist() == [0.5, 0.25, 0, 0]
    assert m.ids[0, 2].tolist() == [low, high, 0, 0] and m.coverage[0, 2].tolist() == [0.5, 0.5, 0, 0]
    c = rank_coverage({"ball": np.array([[0.2]]), "box": np.array([[0.7]]), "vase": np.array([[0.1]])}, ranks=2)
    assert c.ids[0, 0].tolist() == [box, ball] and c.coverage[0, 0].tolist() == pytest.approx([0.7, 0.2])
    r = ranked_matte(np.array([[2, -1]]), names, ranks=2, edge_pixels=np.array([1]),
                     edge_samples=np.array([[2, 1, 1, -1]]))
    assert r.ids[0].tolist() == [[vase, 0], [box, vase]] and r.coverage[0].tolist() == [[1, 0], [0.5, 0.25]]


def test_ranked_coverage_maps_sum_colliding_names_and_say_bad_input():
    """rank_coverage: per-pixel ranks of (H, W) maps of any shape, one name alone, the maps of
    two names whose ids collide summed (the specification merges them), and a clear error for
    no map or maps of different shapes."""
    a, b = "object87560", "object154030"  # two names with one id
    assert name_to_bits(a) == name_to_bits(b)
    cov = {a: np.full((2, 3), 0.25), b: np.full((2, 3), 0.5), "box": np.linspace(0, 1, 6).reshape(2, 3)}
    m = rank_coverage(cov, ranks=2)
    assert m.ids.shape == (2, 3, 2) and m.ranks == 2
    merged, box = np.float32(name_to_id(a)), np.float32(name_to_id("box"))
    assert m.ids[0, 0].tolist() == [merged, 0] and m.coverage[0, 0].tolist() == [0.75, 0]  # box: 0 there
    assert m.ids[1, 2].tolist() == [box, merged] and m.coverage[1, 2].tolist() == [1.0, 0.75]
    one = rank_coverage({"box": np.array([[0.5, 0.0]])}, ranks=1)
    assert one.ids.tolist() == [[[box], [0]]] and one.coverage.tolist() == [[[0.5], [0]]]
    with pytest.raises(ValueError, match="^coverage is empty: give the frame size with at least one name$"):
        rank_coverage({})
    with pytest.raises(ValueError, match=r"coverage of 'vase' has shape \(1, 2\), expected \(2, 3\)"):
        rank_coverage({"box": np.zeros((2, 3)), "vase": np.zeros((1, 2))})


def test_a_ranked_matte_gives_the_exr_channels_and_each_names_matte():
    """RankedMatte.channels: {type}00.R/G/B/A = ids and coverages of ranks 0 and 1, {type}01 of
    ranks 2 and 3, an odd rank count padded with an empty rank, float32 whatever it was given;
    matte(name or id) sums the coverage of that id over the ranks, as a compositor's decoder does."""
    ids = np.array([[[1.5, 2.5, 3.5], [2.5, 0, 0]]], np.float64)
    cov = np.array([[[0.5, 0.3, 0.2], [1.0, 0, 0]]], np.float64)
    ch = RankedMatte(ids, cov).channels("CryptoObject")
    assert sorted(ch) == sorted(f"CryptoObject{i:02d}.{c}" for i in range(2) for c in "RGBA")
    assert all(v.dtype == np.float32 and v.shape == (1, 2) and v.flags.c_contiguous for v in ch.values())
    assert ch["CryptoObject00.R"].tolist() == [[1.5, 2.5]] and ch["CryptoObject00.G"].tolist() == [[0.5, 1.0]]
    assert ch["CryptoObject00.B"].tolist() == [[2.5, 0]] and ch["CryptoObject00.A"].tolist() == [[np.float32(0.3), 0]]
    assert ch["CryptoObject01.R"].tolist() == [[3.5, 0]] and ch["CryptoObject01.G"].tolist() == [[np.float32(0.2), 0]]
    assert ch["CryptoObject01.B"].tolist() == [[0, 0]] and ch["CryptoObject01.A"].tolist() == [[0, 0]]
    m = rank_samples(np.array([[[0, 1, 1, -1], [1, 1, 1, 1]]]), ["ball", "box"], ranks=2)
    box = m.matte("box")
    assert box.dtype == np.float32 and box.tolist() == [[0.5, 1.0]]
    assert m.matte(name_to_id("ball")).tolist() == [[0.25, 0]] and m.matte("vase").tolist() == [[0, 0]]


# --- the EXR -----------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def exr_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("exr")
    return render(tmp, "--size", "160x120", "--exr", "--depth", "--objectid", "--bands", "3")


def test_exr_has_every_layer_and_the_cryptomatte_header(exr_run):
    ch, hdr = read_exr(exr_run / "frame_0001.exr")
    crypto = {f"{t}{i:02d}.{c}" for t in ("CryptoObject", "CryptoMaterial") for i in range(2) for c in "RGBA"}
    lines = {f"lines{k}.{c}" for k in ("", "_silhouette", "_border", "_crease") for c in "RGBA"}
    assert set(ch) == {"Z", "N.X", "N.Y", "N.Z", "R", "G", "B", "A", "bands.V"} | crypto | lines
    assert ch["Z"].dtype == np.float32 and ch["CryptoObject00.R"].dtype == np.float32
    manifest = json.loads(hdr[f"cryptomatte/{layer_key('CryptoObject')}/manifest"])
    assert manifest == {n: name_to_hex(n) for n in OBJECTS}
    assert hdr[f"cryptomatte/{layer_key('CryptoMaterial')}/name"] == "CryptoMaterial"


def test_exr_layers_asked_for_and_no_others(tmp_path):
    out = render(tmp_path, "--size", "64x48", "--exr", "--exr-layers", "depth,crypto", "--no-svg")
    ch, _ = read_exr(out / "frame_0001.exr")
    assert {c.split(".")[0] for c in ch} == {"Z", "CryptoObject00", "CryptoObject01",
                                             "CryptoMaterial00", "CryptoMaterial01"}
    assert not (out / "bands").exists(), "the EXR alone asks for no PNG"


def test_cryptomatte_coverage_sums_to_alpha_and_picks_objects(exr_run):
    ch, _ = read_exr(exr_run / "frame_0001.exr")
    total = sum(ch[f"CryptoObject{i:02d}.{c}"].astype(np.float64) for i in range(2) for c in "GA")
    assert np.abs(total - ch["A"].astype(np.float64)).max() <= 1 / 255
    # Each object's matte: where it has coverage, the object-id PNG sees it at the pixel centre
    # somewhere; a name not in the scene has no matte.
    oid = np.asarray(Image.open(exr_run / "objectid" / "frame_0001.png"))
    ids = [ch[f"CryptoObject{i:02d}.{c}"] for i in range(2) for c in "RB"]
    for k, name in enumerate(OBJECTS):
        matte = sum(np.where(i.view(np.uint32) == np.float32(name_to_id(name)).view(np.uint32), 1.0, 0.0) for i in ids)
        full = (oid == k + 1)
        if full.any():
            assert (matte[full] > 0).all(), name
    assert not any((i.view(np.uint32) == np.float32(name_to_id("nothing")).view(np.uint32)).any() for i in ids)


def test_cryptomatte_ranks_in_the_exr_go_by_descending_coverage(exr_run):
    """In the file a compositor reads: at every pixel the coverage of rank 0 (CryptoObject00.G) is
    the highest, each further rank's no higher than the one before, and a rank without coverage
    has id 0; on the frame's object edges pixels hold two ranks or more."""
    ch, _ = read_exr(exr_run / "frame_0001.exr")
    for t in ("CryptoObject", "CryptoMaterial"):
        cov = np.stack([ch[f"{t}{i:02d}.{c}"] for i in range(2) for c in "GA"])
        ids = np.stack([ch[f"{t}{i:02d}.{c}"] for i in range(2) for c in "RB"])
        assert (cov[1] > 0).sum() > 50, t  # the frame has mixed pixels
        assert (np.diff(cov, axis=0) <= 0).all(), t
        assert (ids[cov == 0].view(np.uint32) == 0).all(), t


def test_the_compiled_ranks_of_mixed_pixels_are_rank_samples_ranks():
    """crypto_ranks (the mixed pixels' ranks, compiled) gives rank_samples' ids and coverages bit
    for bit on random samples of few ids: ties (broken by ascending id bits), background samples,
    pixels of more ids than ranks and pixels of background only."""
    from strokekit.cryptomatte import id_table
    from strokekit.raster.hits import compiled

    rng = np.random.default_rng(2)
    names = ["ball", "box", "vase", "ring", "ground"]
    samples = rng.integers(-1, len(names), (3000, 16)).astype(np.int32)
    samples[:500] = rng.integers(-1, 2, (500, 16))  # two ids and background: many ties
    samples[500] = -1
    ref = rank_samples(samples[None], names, 4)
    slot_of, uniq = id_table(names)
    ids, cov = np.zeros((4, 3000), np.float32), np.zeros((4, 3000), np.float32)
    compiled().crypto_ranks(np.where(samples >= 0, slot_of[np.maximum(samples, 0)], -1).astype(np.int32),
                            uniq.view(np.float32), ids, cov)
    assert ids.T.tobytes() == ref.ids[0].tobytes() and cov.T.tobytes() == ref.coverage[0].tobytes()
    assert (ref.coverage[0, :500, 0] == ref.coverage[0, :500, 1]).sum() > 20  # (ties were there)


def test_the_frames_cryptomatte_is_the_ranked_matte_of_its_samples():
    """crypto_layers (rank 0 of the uniform pixels compiled, only the filled upper ranks
    scattered) gives the ranked matte cryptomatte.ranked_matte makes of the same samples, bit for
    bit: the object or material of each pixel's representative sample, and the mixed pixels'
    ranks of their R x R samples; the still life's frame has pixels of two ranks or more."""
    from strokekit.camera.paths import orbit_path
    from strokekit.cryptomatte import ranked_matte
    from strokekit.raster.bands import RasterOptions, render_raster, representative
    from strokekit.raster.passes import RANKS, crypto_layers
    from strokekit.scene.load import load_scene
    from strokekit.scene.occluder import Occluder

    s = load_scene(SAMPLE)
    cam = orbit_path(s.center, s.radius, 2, width=200, height=150).cameras[1]
    frame = render_raster(s, cam, Occluder(s), RasterOptions(bands=3, pngs=False))
    face = representative(frame.hits.face, frame.K)
    m = frame.mixed
    layers = crypto_layers(frame)
    for layer, table, names in zip(layers, (s.face_object, s.face_material),
                                   (tuple(s.objects), tuple(x.name for x in s.materials))):
        base = np.where(face >= 0, table[np.maximum(face, 0)], -1)
        edge = np.where(m.face >= 0, table[np.maximum(m.face, 0)], -1)
        ref = ranked_matte(base, names, RANKS, m.pixels, edge)
        assert layer.names == names
        assert layer.ids.tobytes() == ref.ids.tobytes() and layer.coverage.tobytes() == ref.coverage.tobytes()
        assert (layer.coverage[..., 1] > 0).sum() > 20, layer.type_name


def test_exr_depth_is_the_ray_cast_view_depth(exr_run):
    """Z at pixels away from silhouettes equals the view depth of an Embree ray through the sample
    nearest the pixel centre within 1e-5 relative; background is 1e10."""
    from strokekit.camera.paths import orbit_path
    from strokekit.raster.rays import cast_samples
    from strokekit.scene.load import load_scene
    from strokekit.scene.occluder import Occluder

    ch, _ = read_exr(exr_run / "frame_0001.exr")
    z = ch["Z"].astype(np.float64)
    s = load_scene(SAMPLE)
    cam = orbit_path(s.center, s.radius, 2, width=160, height=120).cameras[0]
    rng = np.random.default_rng(0)
    fg = np.argwhere(z[1:-1, 1:-1] < BACKGROUND_DEPTH) + 1
    pick = np.concatenate([fg[rng.choice(len(fg), 300)], rng.integers(1, (119, 159), (100, 2))])
    py, px = pick[:, 0], pick[:, 1]
    f = cam.focal_px
    k = QUALITY_PRESETS["default"]["supersample"]
    c = (k // 2 + 0.5) / k  # the sample nearest the pixel centre (the centre itself at k = 1)
    ref = cast_samples(cam, Occluder(s), (px + c - 80) / f, (60 - (py + c)) / f)["depth"].astype(np.float64)
    bg = ~np.isfinite(ref)
    assert np.all(z[py[bg], px[bg]] == BACKGROUND_DEPTH)
    # interior pixels: the 3 x 3 neighbourhood is all foreground at about the same depth
    nb = np.stack([z[py + dy, px + dx] for dy in (-1, 0, 1) for dx in (-1, 0, 1)])
    inner = ~bg & (nb.max(axis=0) < 2 * nb.min(axis=0)) & (nb.max(axis=0) < BACKGROUND_DEPTH)
    assert inner.sum() > 100
    rel = np.abs(z[py[inner], px[inner]] - ref[inner]) / ref[inner]
    assert rel.max() <= 1e-5


def test_exr_bytes_are_deterministic(tmp_path):
    a = render(tmp_path, "--size", "64x48", "--exr", out="a")
    b = render(tmp_path, "--size", "64x48", "--exr", out="b")
    assert (a / "frame_0001.exr").read_bytes() == (b / "frame_0001.exr").read_bytes()


@pytest.mark.parametrize("codec", ["zips", "rle", "piz", "none"])
def test_every_exr_codec_gives_back_the_same_channels(tmp_path, codec):
    """--exr-codec trades size for encoding time; being lossless, each gives back the ZIP file's
    channels bit for bit (Cryptomatte ids are float bit patterns: any rounding would lose them)."""
    import OpenEXR

    ref = render(tmp_path, "--size", "64x48", "--exr", "--exr-codec", "zip", "--no-svg", out="zip")
    out = render(tmp_path, "--size", "64x48", "--exr", "--exr-codec", codec, "--no-svg", out=codec)
    a, _ = read_exr(ref / "frame_0001.exr")
    b, hdr = read_exr(out / "frame_0001.exr")
    assert hdr["compression"] == getattr(OpenEXR, f"{codec.upper()}_COMPRESSION" if codec != "none" else "NO_COMPRESSION")
    assert sorted(a) == sorted(b)
    for name in a:
        assert a[name].dtype == b[name].dtype and a[name].tobytes() == b[name].tobytes(), name


def _runs(rng, n: int, dtype) -> np.ndarray:
    """n values in runs of 1 to 300 equal values (RLE's runs and literals of every length)."""
    out = np.empty(0, dtype)
    while out.size < n:
        out = np.concatenate([out, np.full(rng.integers(1, 300), rng.normal(), dtype)])
    return out[:n]


@pytest.mark.parametrize("codec", ["rle", "none"])
def test_the_compiled_writer_writes_the_bytes_openexr_writes(tmp_path, codec):
    """RLE and uncompressed files are written by strokekit's compiled writer: the very bytes
    OpenEXR writes of the same channels and attributes. An odd width (a float32 plane after a
    half one starts at an odd byte), half and float32 planes, zero, constant and noisy rows, runs
    of every length, rows RLE would grow (OpenEXR stores them as they are) and an attribute name
    past 31 bytes (the version's long-names flag); read back, every channel is bit for bit."""
    from strokekit.writers.exr import compiled_exr

    rng = np.random.default_rng(3)
    H, W = 19, 37
    noise = rng.integers(0, 2 ** 16, (H, W), dtype=np.uint16).view(np.float16)
    ch = {"A": noise, "B": np.zeros((H, W), np.float16), "C": _runs(rng, H * W, np.float16).reshape(H, W),
          "Z": rng.normal(size=(H, W)).astype(np.float32), "id.R": np.full((H, W), 3.5e-12, np.float32),
          "id.G": _runs(rng, H * W, np.float32).reshape(H, W)}
    ch["C"][4] = noise[4]
    for a in ch.values():  # row 7 all noise: RLE would grow it
        a[7] = rng.integers(0, 256, a[7].nbytes, dtype=np.uint8).view(a.dtype)
    attrs = {"strokekit/layers": "{}", "cryptomatte/3ae39a5/a-name-longer-than-31-bytes": "x"}
    ours = compiled_exr(ch, attrs, codec)
    assert ours == openexr_file(ch, attrs, codec)
    if codec == "rle":  # (the test holds what it says: RLE shrank rows, and stored row 7 as it is)
        table = next(p for p in range(len(ours)) if int.from_bytes(ours[p:p + 8], "little") == p + 8 * H)
        chunk = [int.from_bytes(ours[table + 8 * y:table + 8 * y + 8], "little") for y in range(H)]
        size = [int.from_bytes(ours[c + 4:c + 8], "little") for c in chunk]
        row = sum(a[0].nbytes for a in ch.values())
        assert size[7] == row and max(size[:7]) < row
    (tmp_path / "f.exr").write_bytes(ours)
    back, _ = read_exr(tmp_path / "f.exr")
    assert sorted(back) == sorted(ch)
    for n, a in ch.items():
        assert back[n].dtype == a.dtype and back[n].tobytes() == a.tobytes(), n


@pytest.mark.parametrize("codec", ["rle", "none"])
def test_the_compiled_writer_casts_float32_to_half_as_numpy_does(codec):
    """A float32 plane the file holds in half (the colour, normal and band planes) is cast as the
    compiled writer writes it: the bytes of the file OpenEXR writes of numpy's cast, for values
    that round to even, underflow to subnormals and zero, overflow to inf, and NaNs."""
    from strokekit.writers.exr import _compiled_exr

    rng = np.random.default_rng(5)
    H, W = 24, 50
    edge = np.array([0.0, -0.0, 1.0, 65504.0, 65520.0, 1e6, -1e6, np.inf, -np.inf, np.nan, 5.96e-8, 2.98e-8, 1e-9,
                     6.1e-5, -3e-6, 1.0 + 2 ** -11, 1.0 + 3 * 2 ** -11, 2049.0, 2051.0], np.float32)
    bits = rng.integers(0, 2 ** 32, H * W, dtype=np.uint64).astype(np.uint32)
    bits[:edge.size] = edge.view(np.uint32)
    bits[edge.size:edge.size + 200] = np.arange(0x7F800001, 0x7F800001 + 200 * 4099, 4099, dtype=np.uint32)  # NaNs
    f32 = bits.view(np.float32).reshape(H, W)
    smooth = rng.normal(size=(H, W)).astype(np.float32)
    with np.errstate(over="ignore"):
        ref = openexr_file({"A": f32.astype(np.float16), "B": smooth.astype(np.float16), "Z": smooth}, {}, codec)
    assert _compiled_exr({"A": (f32, np.float16), "B": (smooth, np.float16), "Z": (smooth, np.float32)}, {},
                         codec) == ref


@pytest.mark.parametrize("codec", ["rle", "none"])
def test_sparse_half_planes_are_written_as_their_dense_planes(codec):
    """The lines layers reach the compiled writer as their covered pixels only (SparsePlane): the
    file is the one OpenEXR writes of the dense planes, RLE-coded or stored as they are (none),
    with a row covered throughout (row 2) and one without a covered pixel (row 5); sparse planes
    of other pixels than each other's are refused."""
    from strokekit.writers.exr import SparsePlane, _compiled_exr

    rng = np.random.default_rng(11)
    H, W = 9, 21
    pix = np.sort(rng.choice(H * W, 40, replace=False))
    pix = pix[pix // W != 5]  # row 5: nothing covered
    noise = rng.integers(0, 2 ** 16, (H, W), dtype=np.uint16).view(np.float16)
    noise[2] = rng.integers(0, 2 ** 16, W, dtype=np.uint16).view(np.float16)
    planes, sources = {}, {"N": (noise, np.float16)}
    for name in ("lines.A", "lines.R"):
        vals = rng.normal(size=pix.size).astype(np.float16)
        dense = np.zeros(H * W, np.float16)
        dense[pix] = vals
        planes[name] = dense.reshape(H, W)
        sources[name] = SparsePlane(pix, vals, (H, W)), np.float16
    planes["lines.A"][2] = noise[2]  # row 2: every pixel of it in the sparse planes
    row2 = np.arange(2 * W, 3 * W)
    a_pix = np.union1d(pix, row2)
    sources["lines.A"] = SparsePlane(a_pix, planes["lines.A"].reshape(-1)[a_pix], (H, W)), np.float16
    sources["lines.R"] = SparsePlane(a_pix, planes["lines.R"].reshape(-1)[a_pix], (H, W)), np.float16
    assert _compiled_exr(sources, {}, codec) == openexr_file({"N": noise, **planes}, {}, codec)
    sources["lines.R"] = SparsePlane(pix, planes["lines.R"].reshape(-1)[pix], (H, W)), np.float16
    with pytest.raises(ValueError, match="share their pixels"):
        _compiled_exr(sources, {}, codec)


def test_a_frame_written_by_the_compiled_writer_is_openexrs_file(tmp_path):
    """A rendered frame with every layer (Cryptomatte manifests, the strokekit/layers header),
    in RLE (`--exr-codec rle`, the compiled writer): the file the run wrote is byte for byte the one
    OpenEXR writes of its channels and header."""
    import OpenEXR

    codec = "rle"
    out = render(tmp_path, "--size", "64x48", "--exr", "--exr-codec", "rle", "--bands", "3", "--no-svg")
    ch, hdr = read_exr(out / "frame_0001.exr")
    attrs = {k: v for k, v in hdr.items() if k.startswith(("cryptomatte/", "strokekit/"))}
    assert len(attrs) == 9 and len(ch) == 41 and hdr["compression"] == OpenEXR.RLE_COMPRESSION
    assert (out / "frame_0001.exr").read_bytes() == openexr_file(ch, attrs, codec)


#: The channels Blender writes in half float in a multilayer EXR ("Float (Half)" colour passes);
#: depth and Cryptomatte stay float32.
HALF_LAYERS = ("N", "RGBA", "bands", "lines")


def _layer(channel: str) -> str:
    return channel.rsplit(".", 1)[0] if "." in channel else ("RGBA" if channel in "RGBA" else channel)


def test_exr_floats_are_blenders_and_the_header_says_what_each_layer_holds(exr_run):
    """By default colour, normals, band labels and lines are half float, depth and Cryptomatte
    float32 (as Blender writes them); the strokekit/layers attribute gives each layer's type and
    what it holds, in agreement with the channels."""
    ch, hdr = read_exr(exr_run / "frame_0001.exr")
    said = json.loads(hdr["strokekit/layers"])
    assert set(said) == {_layer(c) for c in ch}
    for name, a in ch.items():
        half = _layer(name).startswith(HALF_LAYERS)
        assert a.dtype == (np.float16 if half else np.float32), name
        assert said[_layer(name)]["type"] == ("half" if half else "float"), name
    assert "1e10" in said["Z"]["holds"] and "premultiplied" in said["RGBA"]["holds"]


def test_exr_float_full_writes_every_channel_float32_with_the_same_values(tmp_path):
    """--exr-float full: every channel float32 (the header says so); the half channels of the
    default file are those values rounded to half, the float32 ones the same bits."""
    half = render(tmp_path, "--size", "64x48", "--exr", "--no-svg", out="half")
    full = render(tmp_path, "--size", "64x48", "--exr", "--exr-float", "full", "--no-svg", out="full")
    a, _ = read_exr(half / "frame_0001.exr")
    b, hdr = read_exr(full / "frame_0001.exr")
    assert sorted(a) == sorted(b)
    assert {v["type"] for v in json.loads(hdr["strokekit/layers"]).values()} == {"float"}
    for name in a:
        assert b[name].dtype == np.float32, name
        assert b[name].astype(a[name].dtype).tobytes() == a[name].tobytes(), name
    assert any(a[n].dtype == np.float16 and (b[n] != b[n].astype(np.float16)).any() for n in a), \
        "no channel holds a value half float rounds: the test would not see a half channel written"


def test_exr_codec_without_exr_is_a_usage_error(tmp_path, capsys):
    with pytest.raises(SystemExit) as e:
        main(["render", str(SAMPLE), "--orbit", "2", "--frames", "1", "-q", "--out", str(tmp_path / "o"),
              "--exr-codec", "rle"])
    assert e.value.code == 2
    assert "--exr-codec needs --exr" in capsys.readouterr().err


# --- the lines raster ------------------------------------------------------------------------------

def test_lines_png_agrees_with_the_svg_rendered_by_cairo(tmp_path):
    """The lines raster covers what a real SVG renderer draws of the SVG: coverage IoU >= 0.98 at
    1024 x 1024 on the still life."""
    try:
        import cairosvg
    except (ImportError, OSError) as e:  # OSError: the cairo library itself is missing
        pytest.skip(f"cairosvg cannot load: {e}")
    out = render(tmp_path, "--size", "1024x1024", "--lines-png")
    ours = np.asarray(Image.open(out / "lines" / "frame_0001.png")).astype(np.float64)[..., 3] / 255
    png = cairosvg.svg2png(bytestring=(out / "frame_0001.svg").read_bytes(), output_width=1024, output_height=1024)
    ref = np.asarray(Image.open(io.BytesIO(png)).convert("RGBA")).astype(np.float64)[..., 3] / 255
    iou = np.minimum(ours, ref).sum() / np.maximum(ours, ref).sum()
    assert iou >= 0.98, iou


# --- PNG passes: names, colour spaces, metadata ----------------------------------------------------

def test_every_pass_file_name_ends_with_the_frame_number(tmp_path):
    """Compositors (Blender's image-sequence detection among them) take the last number of a file
    name as its frame: every per-frame file of a run with every pass has the frame number last,
    and each pass is a folder of its own sequence."""
    with pytest.raises(SystemExit):
        main([str(a) for a in ["render", SAMPLE, "--orbit", "3", "-q", "--out", tmp_path / "o", "--size", "48x36",
                               "--bands", "3", "--masks", "--objectid", "--depth", "--fill", "--exr", "--lines-png",
                               "--gltf"]])
    files = [p for p in (tmp_path / "o").rglob("*") if p.is_file() and not p.name.startswith(".")]
    folders = {p.parent.name for p in files if p.suffix == ".png"}
    assert folders == {"bands", "shade", "mask1", "mask2", "mask3", "objectid", "depth", "fill", "lines"}
    for p in files:
        last = re.findall(r"\d+", p.name)[-1]
        assert 1 <= int(last) <= 3, p
    for folder in folders:
        assert sorted(p.name for p in (tmp_path / "o" / folder).iterdir()) == [
            "frame_0001.png", "frame_0002.png", "frame_0003.png"]


def test_png_colour_spaces_and_the_depth_range(exr_run):
    """Colour passes carry an sRGB chunk; data passes none and 'colorspace: Non-Color'; the depth
    PNG records its near/far range, the same as the frame JSON; the JSON names the objects with
    their object-id values and Cryptomatte ids."""
    shade = Image.open(exr_run / "shade" / "frame_0001.png")
    bands = Image.open(exr_run / "bands" / "frame_0001.png")
    depth = Image.open(exr_run / "depth" / "frame_0001.png")
    assert "srgb" in shade.info and "colorspace" not in shade.info
    assert "srgb" not in bands.info and bands.info["colorspace"] == "Non-Color"
    doc = json.loads((exr_run / "frame_0001.json").read_text())["raster"]
    assert [float(depth.info["near"]), float(depth.info["far"])] == doc["depth_range"]
    assert [o["name"] for o in doc["objects"]] == list(OBJECTS)
    assert [o["objectid"] for o in doc["objects"]] == [1, 2, 3, 4, 5]
    assert all(o["cryptomatte"] == name_to_hex(o["name"]) for o in doc["objects"] + doc["materials"])
