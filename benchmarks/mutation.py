"""Mutation testing of the modules whose mistakes users cannot see at a glance (mutmut 3).

    .venv/bin/python -m pip install mutmut      # into the venv that runs the tests
    nice -n 15 .venv/bin/python benchmarks/mutation.py                 # every module below
    nice -n 15 .venv/bin/python benchmarks/mutation.py cryptomatte     # some of them

Not CI: a module takes minutes to an hour. Each module runs in a scratch copy of the project
(`--work`, default $TMPDIR/strokekit-mutation/<module>: mutmut writes its `mutants/` tree
there, and a rerun only tests the mutants of functions that changed), against the tests that
cover it, one mutant at a time. Prints, per module, the mutants killed, the equivalent ones
(EQUIVALENT below: a change no input can tell apart, with the reason) and the others that
survived, with their diffs; the score is killed / (all - equivalent).

When a module moves or its covering tests change, edit MODULES; when a function changes, the
equivalent mutants listed for it may no longer be (their lines are shown when they survive).
"""

from __future__ import annotations

import argparse
import fnmatch
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

#: Tests left out of every module's run: a second cluster, and tests whose subprocess is
#: stopped on a timer (a slower mutant makes them fail for no fault of its own).
NOT_FOR_MUTANTS = "not dask and not killed_run and not ctrl_c_during_render and not open3d"

#: name: (files to mutate, the functions of them to mutate (mutmut's mutant names, globs; empty:
#: all), the tests that cover them: pytest arguments from the project root).
MODULES: dict[str, tuple[tuple[str, ...], tuple[str, ...], tuple[str, ...]]] = {
    "occlusion": (("strokekit/lines/occlusion.py", "strokekit/lines/levels.py"), (),
                  ("tests/test_hidden.py", "-m", "not slow")),
    "cryptomatte": (("strokekit/cryptomatte.py",), (), ("tests/test_exr.py",)),
    "atomic-files": (("strokekit/fileio.py",), (), ("tests/test_cli.py", "tests/test_faults.py", "tests/test_pipeline.py",
                                                    "-k", "readable or pattern or unwritable or report_where or "
                                                    "read_only or atomic or empty_output or failed_write or "
                                                    "small_filesystem or temporaries or interrupted or removes")),
    "resume": (("strokekit/run/resume.py", "strokekit/run/runner.py", "strokekit/run/manifest.py"),
               ("strokekit.run.resume.*",) + tuple(f"strokekit.run.runner.{f}__mutmut_*" for f in (
                   "x_check_files_apart", "xǁFrameStreamǁenter_written")) + ("strokekit.run.manifest.*",),
               ("tests/test_pipeline.py", "tests/test_faults_units.py", "tests/test_manifest.py", "-k",
                "test_manifest or skip_existing or temporaries or failed_run_removes or two_runs or stopped_rerun or interrupted or "
                "whole_just_before or resume_after or write_error or over_an_input or sequence_after")),
    "camera-file": (("strokekit/camera/paths.py",), (), ("tests/test_camera_path.py", "tests/test_gltf_camera.py",
                                                        "tests/test_faults.py", "-k", "camera or keyframe or up")),
    "svg-writer": (("strokekit/writers/svg.py",), (), ("tests/test_golden.py", "tests/test_hidden.py",
                                                        "tests/test_raster.py", "-m", "not slow", "-k",
                                                        "golden or svg or polygons or dash or layer")),
    "diff": (("strokekit/metrics/diff.py",), (), ("tests/test_diff.py",)),
}

#: Mutants that behave as the original on every input, by module: (function, the mutated line
#: as mutmut shows it, stripped) -> why. Not counted in the score.
EQUIVALENT: dict[str, dict[tuple[str, str], str]] = {
    "occlusion": {
        ('occlusion_runs', 'limit = min(hi_level, MAX_OCCLUSION) + 2  # counting further changes nothing kept'):
            'counting past hi + 1 only splits pieces deeper than hi, which the range drops',
        ('occlusion_runs', 'whole = L <= options.whole_edge_px'):
            'differs only for an edge exactly whole_edge_px long',
        ('occlusion_runs', 'if len(keep_cx) <= len(cx_seg):'):
            'filtering with a mask that keeps everything keeps the same arrays',
        ('occlusion_runs', 'cx_delta[ends[cx_seg, 1] < 0] = NO_DELTA'):
            'more crossings without a known delta: their levels are counted by rays instead (the same levels)',
        ('occlusion_runs', 'cx_delta[ends[cx_seg, 0] <= 0] = NO_DELTA'):
            'more crossings without a known delta: their levels are counted by rays instead (the same levels)',
        ('occlusion_runs', 'cx_delta[ends[cx_seg, 0] < 1] = NO_DELTA'):
            'more crossings without a known delta: their levels are counted by rays instead (the same levels)',
        ('occlusion_runs', 'last[-2:] = True'):
            'last[-2] is overwritten by the np.not_equal on the next line',
        ('occlusion_runs', 'assert np.array_equal(run_seg, e_seg[o_end]), "XXlevel changes must pair upXX"'):
            'the message of an assertion that holds',
        ('occlusion_runs', 'assert np.array_equal(run_seg, e_seg[o_end]), "LEVEL CHANGES MUST PAIR UP"'):
            'the message of an assertion that holds',
        ('occlusion_runs', 'code = runs.kind.astype(None) + N_KINDS * np.minimum(level, MAX_OCCLUSION)'):
            'dtype only: the kind codes are the same integers, cast where they are used',
        ('occlusion_runs', 'key1=runs.key1, kind=code.astype(None), face=runs.face)'):
            'dtype only: the kind codes are the same integers, cast where they are used',
        ('_by_segment_then_s', 'o = np.argsort(seg, kind=None)'):
            'an unstable sort is caught by the order check (lexsort then); equal (segment, s) keys are runs of no length',
        ('_by_segment_then_s', 'o = np.argsort(seg, )'):
            'an unstable sort is caught by the order check (lexsort then); equal (segment, s) keys are runs of no length',
        ('_by_segment_then_s', 'o = np.argsort(seg, kind="STABLE")'):
            'numpy reads the sort kind case-insensitively',
        ('_by_segment_then_s', 'if len(o) > 1 or not ((so[1:] != so[:-1]) | (ss[1:] >= ss[:-1])).all():'):
            'a stricter order check: np.lexsort, the reference, more often',
        ('_by_segment_then_s', 'if len(o) >= 1 and not ((so[1:] != so[:-1]) | (ss[1:] >= ss[:-1])).all():'):
            'a stricter order check: np.lexsort, the reference, more often',
        ('_by_segment_then_s', 'if len(o) > 1 and not ((so[1:] != so[:-1]) & (ss[1:] >= ss[:-1])).all():'):
            'a stricter order check: np.lexsort, the reference, more often',
        ('_by_segment_then_s', 'if len(o) > 1 and not ((so[1:] != so[:-1]) | (ss[1:] > ss[:-1])).all():'):
            'a stricter order check: np.lexsort, the reference, more often',
        ('_by_segment_then_s', 'if len(o) > 2 and not ((so[1:] != so[:-1]) | (ss[1:] >= ss[:-1])).all():'):
            'two entries of one segment are its start (s 0) or end (s 1) and one change: in order either way',
        ('own_faces', 'faces = np.full((len(idx), 2), -1, None)'):
            'np.full infers int64 from the fill value -1',
        ('own_faces', 'faces = np.full((len(idx), 2), -1, )'):
            'np.full infers int64 from the fill value -1',
        ('crossing_deltas', 'np.ascontiguousarray(edge, None), end_px, gap, np.ascontiguousarray(ab), np.ascontiguousarray(own),'):
            'dtype, copy or contiguity of an argument whose values stay the same (an empty mask has none)',
        ('crossing_deltas', 'np.ascontiguousarray(edge, ), end_px, gap, np.ascontiguousarray(ab), np.ascontiguousarray(own),'):
            'dtype, copy or contiguity of an argument whose values stay the same (an empty mask has none)',
        ('crossing_deltas', 'scene.edges.astype(np.int64, copy=None), scene.edge_faces, scene.edge_face_count.astype(np.int64, copy=False),'):
            'dtype, copy or contiguity of an argument whose values stay the same (an empty mask has none)',
        ('crossing_deltas', 'scene.edges.astype(np.int64, ), scene.edge_faces, scene.edge_face_count.astype(np.int64, copy=False),'):
            'dtype, copy or contiguity of an argument whose values stay the same (an empty mask has none)',
        ('crossing_deltas', 'scene.edges.astype(np.int64, copy=True), scene.edge_faces, scene.edge_face_count.astype(np.int64, copy=False),'):
            'dtype, copy or contiguity of an argument whose values stay the same (an empty mask has none)',
        ('crossing_deltas', 'scene.edges.astype(np.int64, copy=False), scene.edge_faces, scene.edge_face_count.astype(None, copy=False),'):
            'dtype, copy or contiguity of an argument whose values stay the same (an empty mask has none)',
        ('crossing_deltas', 'scene.edges.astype(np.int64, copy=False), scene.edge_faces, scene.edge_face_count.astype(np.int64, copy=None),'):
            'dtype, copy or contiguity of an argument whose values stay the same (an empty mask has none)',
        ('crossing_deltas', 'scene.edges.astype(np.int64, copy=False), scene.edge_faces, scene.edge_face_count.astype(np.int64, ),'):
            'dtype, copy or contiguity of an argument whose values stay the same (an empty mask has none)',
        ('crossing_deltas', 'scene.edges.astype(np.int64, copy=False), scene.edge_faces, scene.edge_face_count.astype(np.int64, copy=True),'):
            'dtype, copy or contiguity of an argument whose values stay the same (an empty mask has none)',
        ('crossing_deltas', 'scene.faces.astype(np.int64, copy=None), scene.vertices, np.asarray(view, float), bool(camera.is_ortho),'):
            'dtype, copy or contiguity of an argument whose values stay the same (an empty mask has none)',
        ('crossing_deltas', 'scene.faces.astype(np.int64, ), scene.vertices, np.asarray(view, float), bool(camera.is_ortho),'):
            'dtype, copy or contiguity of an argument whose values stay the same (an empty mask has none)',
        ('crossing_deltas', 'scene.faces.astype(np.int64, copy=True), scene.vertices, np.asarray(view, float), bool(camera.is_ortho),'):
            'dtype, copy or contiguity of an argument whose values stay the same (an empty mask has none)',
        ('crossing_deltas', 'scene.faces.astype(np.int64, copy=False), scene.vertices, np.asarray(view, None), bool(camera.is_ortho),'):
            'dtype, copy or contiguity of an argument whose values stay the same (an empty mask has none)',
        ('crossing_deltas', 'scene.faces.astype(np.int64, copy=False), scene.vertices, np.asarray(view, ), bool(camera.is_ortho),'):
            'dtype, copy or contiguity of an argument whose values stay the same (an empty mask has none)',
        ('crossing_deltas', 'np.zeros(0, None) if kept is None else kept, NO_DELTA)'):
            'dtype, copy or contiguity of an argument whose values stay the same (an empty mask has none)',
        ('crossing_deltas', 'np.zeros(0, ) if kept is None else kept, NO_DELTA)'):
            'dtype, copy or contiguity of an argument whose values stay the same (an empty mask has none)',
        ('_bisect_levels', 'open_ = np.flatnonzero((hi - lo) * L.take(cs) >= tol_px)'):
            'differs only for a bracket exactly tol_px wide, halved once more',
    },
    "cryptomatte": {
        ("murmur3_32_py", 'k = int.from_bytes(data[4 * i:5 * i + 4], "little")'):
            "the longer slice adds high-order bytes (little-endian), and (k * c1) & mask keeps only the low 32 bits",
        ("murmur3_32_py", 'k = int.from_bytes(data[4 * i:4 * i + 5], "little")'):
            "the longer slice adds high-order bytes (little-endian), and (k * c1) & mask keeps only the low 32 bits",
        ("murmur3_32_py", "k = tail[2] << 16"): "k is 0 just before: ^= and = give the same",
        ("rank_coverage", "acc = np.zeros(shape + (len(uniq),), None)"): "numpy's default dtype is float64",
        ("rank_coverage", "acc = np.zeros(shape + (len(uniq),), )"): "numpy's default dtype is float64",
        ("rank_coverage", "a = np.asarray(coverage[n], dtype=None)"):
            "the map is added into a float64 array, which casts it exactly (ints, bools, float32)",
        ("rank_coverage", "a = np.asarray(coverage[n], )"):
            "the map is added into a float64 array, which casts it exactly (ints, bools, float32)",
        ("rank_coverage", "flat = acc.reshape(-2, len(uniq))"): "numpy reads any negative size as the unknown one",
        ("rank_coverage", "cand = np.where(flat >= 0, cand, -1)"):
            "a zero-coverage candidate has weight 0, and _top_ranks keeps only weights > 0",
        ("rank_coverage", "cand = np.where(flat > 0, cand, +1)"):
            "a zero-coverage candidate has weight 0, and _top_ranks keeps only weights > 0",
        ("rank_coverage", "cand = np.where(flat > 0, cand, -2)"): "_top_ranks reads every slot below 0 as none",
        ("RankedMatte.matte", "return np.where(hit, self.coverage, 0).sum(axis=-1, dtype=None).astype(np.float32)"):
            "an id is in one rank of a pixel at most: the sum has one term, exact in float32",
        ("RankedMatte.matte", "return np.where(hit, self.coverage, 0).sum(axis=-1, ).astype(np.float32)"):
            "an id is in one rank of a pixel at most: the sum has one term, exact in float32",
    },
    "atomic-files": {
        # _read_umask runs once, at import, before mutmut picks a mutant in the test process.
        ("_read_umask", "mask = None"):
            "import time: os.umask(None) raises TypeError, strokekit does not import (every test fails)",
        ("_read_umask", "mask = os.umask(None)"):
            "import time: os.umask(None) raises TypeError, strokekit does not import (every test fails)",
        ("_read_umask", "os.umask(None)"):
            "import time: os.umask(None) raises TypeError, strokekit does not import (every test fails)",
        ("_read_umask", "mask = os.umask(1)"): "os.umask returns the mask before the call, whatever it sets",
        ("atomic_write_text", 'return atomic_write_bytes(path, text.encode("UTF-8"))'):
            "codec names are case-insensitive",
        ("_try_create_in", 'fd, tmp = tempfile.mkstemp(prefix=".strokekit-check.", suffix=None, dir=folder)'):
            "the name of the probe file, removed at once (never seen)",
        ("_try_create_in", 'fd, tmp = tempfile.mkstemp(suffix=TEMP_SUFFIX, dir=folder)'):
            "the name of the probe file, removed at once (never seen)",
        ("_try_create_in", 'fd, tmp = tempfile.mkstemp(prefix=".strokekit-check.", dir=folder)'):
            "the name of the probe file, removed at once (never seen)",
        ("_try_create_in", 'fd, tmp = tempfile.mkstemp(prefix="XX.strokekit-check.XX", suffix=TEMP_SUFFIX, dir=folder)'):
            "the name of the probe file, removed at once (never seen)",
        ("_try_create_in", 'fd, tmp = tempfile.mkstemp(prefix=".STROKEKIT-CHECK.", suffix=TEMP_SUFFIX, dir=folder)'):
            "the name of the probe file, removed at once (never seen)",
    },
    "resume": {
        ('plan_resume', 'stale.unlink(missing_ok=None)'):
            'differs only when another process removes the file between the listing and the unlink',
        ('plan_resume', 'stale.unlink(missing_ok=False)'):
            'differs only when another process removes the file between the listing and the unlink',
        ('remove_temp_files', 'tmp.unlink(missing_ok=None)'):
            'differs only when another process removes the file between the listing and the unlink',
        ('remove_temp_files', 'tmp.unlink(missing_ok=False)'):
            'differs only when another process removes the file between the listing and the unlink',
        ('_digest', 'text = json.dumps(canonical(v), sort_keys=None, separators=(",", ":"), allow_nan=False)'):
            "the digests' spelling: the same in every run of this code, which compares only digests it made",
        ('_digest', 'text = json.dumps(canonical(v), sort_keys=True, separators=None, allow_nan=False)'):
            "the digests' spelling: the same in every run of this code, which compares only digests it made",
        ('_digest', 'text = json.dumps(canonical(v), sort_keys=True, allow_nan=False)'):
            "the digests' spelling: the same in every run of this code, which compares only digests it made",
        ('_digest', 'text = json.dumps(canonical(v), sort_keys=False, separators=(",", ":"), allow_nan=False)'):
            "the digests' spelling: the same in every run of this code, which compares only digests it made",
        ('_digest', 'text = json.dumps(canonical(v), sort_keys=True, separators=("XX,XX", ":"), allow_nan=False)'):
            "the digests' spelling: the same in every run of this code, which compares only digests it made",
        ('_digest', 'text = json.dumps(canonical(v), sort_keys=True, separators=(",", "XX:XX"), allow_nan=False)'):
            "the digests' spelling: the same in every run of this code, which compares only digests it made",
        ('run_manifest', 'scene_d = _digest({"XXcontent_hashXX": scene.content_hash, "objects": len(scene.objects),'):
            "the digests' spelling: the same in every run of this code, which compares only digests it made",
        ('run_manifest', 'scene_d = _digest({"CONTENT_HASH": scene.content_hash, "objects": len(scene.objects),'):
            "the digests' spelling: the same in every run of this code, which compares only digests it made",
        ('FrameStream.enter_written', 'stale = None'):
            'stale is only tested for truth, and [] and None are both false',
    },
    "camera-file": {},
    "svg-writer": {},
    "diff": {},
}

KILLED = {"killed", "timeout", "segfault"}  # a crash or a hang is noticed too


def status_of(code) -> str:
    from mutmut.stats import status_by_exit_code

    return status_by_exit_code[code]


def prepare(work: Path, files: tuple[str, ...], tests: tuple[str, ...]) -> None:
    """A copy of the project's tracked files in `work` (kept between runs: mutmut's results
    are reused where the code did not change), shared/ beside it as the tests expect, and the
    mutmut configuration appended to its pyproject.toml."""
    tracked = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, check=True, capture_output=True).stdout
    work.mkdir(parents=True, exist_ok=True)
    for name in filter(None, tracked.decode().split("\0")):
        src, dst = ROOT / name, work / name
        if not src.is_file():
            continue
        if dst.exists() and dst.read_bytes() == src.read_bytes():
            continue
        dst.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(src, dst)
        stale = work / "mutants" / name  # mutmut regenerates a source it finds changed
        if stale.exists():
            stale.unlink()
    # The CLI is imported as strokekit_cli: a copy of cli/ under that name keeps the tests on this
    # copy's code (the installed one may be another tree's).
    if not (work / "strokekit_cli").exists():
        (work / "strokekit_cli").symlink_to("cli")
    shared = ROOT.parent / "shared"
    # The tests look for ../shared from the copy they run in (work/mutants).
    if shared.exists() and not (work / "shared").exists():
        (work / "shared").symlink_to(shared)
    config = ("\n[tool.mutmut]\n" f"source_paths = [\"strokekit\"]\nonly_mutate = {json.dumps(list(files))}\n"
              f"also_copy = [\"samples\", \"strokekit_cli\"]\npytest_add_cli_args_test_selection = {json.dumps(list(tests))}\n"
              "pytest_add_cli_args = [\"-p\", \"no:cacheprovider\"]\n"
              # (a hung mutant is stopped at 4 x its tests' time, CPU seconds, not mutmut's 30 x)
              "timeout_multiplier = 2.0\n")
    (work / "pyproject.toml").write_text((ROOT / "pyproject.toml").read_text() + config)
    # mutmut copies pyproject.toml into mutants/ once: keep that copy's configuration current too.
    if (work / "mutants").exists():
        shutil.copy2(work / "pyproject.toml", work / "mutants" / "pyproject.toml")


def mutant_diffs(work: Path, names: dict[str, str]) -> dict[str, str]:
    """{mutant: its diff} of the mutants `names` ({mutant: source path}), read by mutmut in one
    process (`mutmut show` is one process each)."""
    if not names:
        return {}
    code = ("import json, sys\nfrom mutmut.mutation.diff_apply import get_diff_for_mutant\n"
            "names = json.loads(sys.stdin.read())\n"
            "print(json.dumps({k: get_diff_for_mutant(k, path=p) for k, p in names.items()}))\n")
    out = subprocess.run([sys.executable, "-c", code], cwd=work, input=json.dumps(names), capture_output=True,
                         text=True, check=True).stdout
    return json.loads(out)


def added_line(diff: str) -> str:
    """The first line a mutant's diff adds, stripped: with its function, what EQUIVALENT names."""
    added = [ln[1:].strip() for ln in diff.splitlines() if ln.startswith("+") and not ln.startswith("+++")]
    return added[0] if added else ""


def function_of(name: str) -> str:
    """strokekit.cryptomatte.x__top_ranks__mutmut_5 -> _top_ranks; methods: Class.method."""
    base = name.rpartition("__mutmut_")[0].rpartition(".")[2]
    if base.startswith("xǁ"):
        return ".".join(base[2:].split("ǁ"))
    return base[2:] if base.startswith("x_") else base


def with_deselection(tests: tuple[str, ...]) -> tuple[str, ...]:
    """The module's pytest arguments, with NOT_FOR_MUTANTS joined to its own -k if it has one."""
    args = list(tests)
    if "-k" in args:
        i = args.index("-k") + 1
        args[i] = f"({args[i]}) and {NOT_FOR_MUTANTS}"
        return tuple(args)
    return (*args, "-k", NOT_FOR_MUTANTS)


def run_module(name: str, work: Path, mutmut: str, show: bool, run: bool = True) -> dict:
    files, functions, tests = MODULES[name]
    if run:
        test_mutants(work, files, functions, with_deselection(tests), mutmut)
    return score_module(name, work, files, functions, tests, mutmut, show)


def test_mutants(work: Path, files, functions, tests, mutmut: str) -> None:
    prepare(work, files, tests)
    # Mutants that survived an earlier run are tried again (the tests may have changed since);
    # mutmut itself keeps every result whose function did not change.
    for path in files:
        meta = work / "mutants" / (path + ".meta")
        if meta.exists():
            data = json.loads(meta.read_text())
            codes = data["exit_code_by_key"]
            data["exit_code_by_key"] = {k: c if c is None or status_of(c) in KILLED else None for k, c in codes.items()}
            meta.write_text(json.dumps(data))
    t = time.time()
    log = work / "mutmut.log"
    with open(log, "w") as f:
        proc = subprocess.run([mutmut, "run", "--max-children", "1", *functions], cwd=work, stdout=f, stderr=subprocess.STDOUT,
                              env=dict(os.environ, PYTHONHASHSEED="0"))
    (work / "seconds").write_text(f"{time.time() - t:.0f}\n")
    if proc.returncode != 0:
        print(f"mutmut exited with {proc.returncode}: see {log}", file=sys.stderr)


def score_module(name: str, work: Path, files, functions, tests, mutmut: str, show: bool) -> dict:
    """Read mutmut's results of module `name` and print them (see the module docstring)."""
    seconds = float((work / "seconds").read_text()) if (work / "seconds").exists() else 0.0
    counts: dict[str, int] = {}
    survivors, equivalent = [], []
    open_ = {}
    for path in files:
        meta = work / "mutants" / (path + ".meta")
        if not meta.exists():
            print(f"{name}: no results for {path} (not run yet; see {work / 'mutmut.log'})", file=sys.stderr)
            continue
        for key, code in json.loads(meta.read_text())["exit_code_by_key"].items():
            if functions and not any(fnmatch.fnmatch(key, f) for f in functions):
                continue
            status = status_of(code)
            if status in KILLED:
                counts["killed"] = counts.get("killed", 0) + 1
            else:
                open_[key] = (path, status)
    diffs = mutant_diffs(work, {k: p for k, (p, _) in open_.items()})
    for key, (_, status) in sorted(open_.items()):
        line = added_line(diffs[key])
        why = EQUIVALENT.get(name, {}).get((function_of(key), line))
        if why is not None:
            equivalent.append((key, line, why))
        else:
            counts[status] = counts.get(status, 0) + 1
            survivors.append((key, status, diffs[key]))
    unchecked = counts.pop("not checked", 0)  # a run stopped early: neither killed nor survived
    total = sum(counts.values()) + len(equivalent)
    counted = total - len(equivalent)
    score = counts.get("killed", 0) / counted if counted else 1.0
    print(f"\n== {name}: {', '.join(files)}  (tests: {' '.join(tests)}; {seconds:.0f} s)")
    print(f"   {total} mutants, {len(equivalent)} equivalent, {counts.get('killed', 0)} of {counted} killed: "
          f"score {100 * score:.1f}%  ({', '.join(f'{k} {v}' for k, v in sorted(counts.items()))})"
          + (f"; {unchecked} not run (the run was stopped)" if unchecked else ""))
    for key, line, why in equivalent:
        print(f"   equivalent {key}: {line}  -- {why}")
    for key, status, diff in survivors:
        if status == "not checked":
            continue
        print(f"   {status} {key}")
        if show:
            print("      " + "\n      ".join(diff.splitlines()[2:]))
    return {"module": name, "files": files, "mutants": total, "equivalent": len(equivalent),
            "killed": counts.get("killed", 0), "score": score, "seconds": seconds,
            "survived": [k for k, _, _ in survivors]}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("modules", nargs="*", help=f"modules to test: {', '.join(MODULES)} (default: all)")
    ap.add_argument("--work", type=Path, default=Path(tempfile.gettempdir()) / "strokekit-mutation",
                    help="folder of the scratch copies (one per module)")
    ap.add_argument("--no-diffs", action="store_true", help="name the surviving mutants without their diffs")
    ap.add_argument("--json", type=Path, help="also write the scores to this file")
    ap.add_argument("--report-only", action="store_true", help="print the results of the last run, run nothing")
    args = ap.parse_args(argv)
    unknown = [m for m in args.modules if m not in MODULES]
    if unknown:
        ap.error(f"unknown module(s) {', '.join(unknown)}: choose from {', '.join(MODULES)}")
    mutmut = shutil.which("mutmut", path=str(Path(sys.executable).parent)) or shutil.which("mutmut")
    if mutmut is None:
        raise SystemExit("mutmut is not installed: python -m pip install mutmut")
    results = [run_module(m, args.work / m, mutmut, not args.no_diffs, run=not args.report_only)
               for m in (args.modules or MODULES)]
    print("\nmodule         mutants  equivalent  killed  score")
    for r in results:
        print(f"{r['module']:<14} {r['mutants']:>7}  {r['equivalent']:>10}  {r['killed']:>6}  {100 * r['score']:5.1f}%")
    if args.json:
        args.json.write_text(json.dumps(results, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
