"""The README's commands run as written, its links lead somewhere, and it stays a front door.

Every ```sh block of the README is run line by line with bash, in a scratch folder that holds the
repository's samples/ and tests/golden/ (so the outputs land there, not in the tree), with this
interpreter's `strokekit` first on PATH. The install steps of the first command are what .ci/run and
.ci/check-wheel do; its render is run here. The test command must be .ci/run's last command."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from helpers import MODELS, ROOT

README = ROOT / "README.md"
FENCE = re.compile(r"^```(\w*)\n(.*?)^```", re.M | re.S)


def blocks(lang: str, page: Path = README) -> list[str]:
    return [body for tag, body in FENCE.findall(page.read_text(encoding="utf-8")) if tag == lang]


def commands(block: str) -> list[str]:
    return [line for line in block.splitlines() if line.strip() and not line.lstrip().startswith("#")]


@pytest.fixture
def workdir(tmp_path) -> Path:
    work = tmp_path / "repo"
    (work / "tests").mkdir(parents=True)
    (work / "samples").symlink_to(ROOT / "samples")
    (work / "tests" / "golden").symlink_to(ROOT / "tests" / "golden")
    if MODELS.exists():  # ../shared/models, as beside the repository
        (tmp_path / "shared").mkdir()
        (tmp_path / "shared" / "models").symlink_to(MODELS)
    return work


def run(line: str, cwd: Path) -> subprocess.CompletedProcess:
    bindir = Path(sys.executable).parent
    assert (bindir / "strokekit").exists(), f"no strokekit beside {sys.executable}: install the package first"
    env = {**os.environ, "PATH": f"{bindir}{os.pathsep}{os.environ.get('PATH', '')}"}
    return subprocess.run(["bash", "-c", line], cwd=cwd, env=env, capture_output=True, text=True, timeout=900)


def test_readme_is_a_front_door():
    """At most 300 lines: the rest is in docs/."""
    n = len(README.read_text(encoding="utf-8").splitlines())
    assert n <= 300, f"README.md has {n} lines"


@pytest.mark.slow
def test_first_command_renders_the_sample_where_it_says(workdir):
    first = blocks("sh")[0].strip()
    assert "\n" not in first, "the fresh-machine command is one line"
    steps = first.split(" && ")
    installs, render = steps[:-1], steps[-1]
    assert [s.split()[0] for s in installs] == ["apt-get", "apt-get", "python3"], installs
    assert installs[-1] == "python3 -m pip install ."
    r = run(render, workdir)
    assert r.returncode == 0, r.stderr
    out = workdir / "out"
    for name in ("frame_0001.svg", "frame_0012.svg", "frame_0012.json", "frame_0012.glb",
                 "bands/frame_0001.png", "shade/frame_0012.png"):
        assert (out / name).stat().st_size > 0, name
    assert not (out / "frame_0013.svg").exists()
    assert "out/" in r.stdout + r.stderr, "the summary says where it wrote"


def test_test_command_is_what_ci_runs():
    """.ci/run ends with the README's test command, word for word."""
    readme_cmd = blocks("sh")[1].strip()
    ci = [line.strip() for line in (ROOT / ".ci" / "run").read_text().splitlines()
          if line.strip() and not line.lstrip().startswith("#")]
    assert ci[-1] == readme_cmd


@pytest.mark.slow
def test_usage_commands_run_as_written(workdir):
    """The 'Using it' commands and the golden-file check, in order, each exiting 0."""
    for block in blocks("sh")[2:]:
        for line in commands(block):
            r = run(line, workdir)
            assert r.returncode == 0, f"{line}\nexit {r.returncode}\n{r.stderr[-2000:]}"
    for name in ("orbit48.json", "dolly.json", "iso.json", "out/frame_0004.json", "lines/frame_0004.svg",
                 "drawing/frame_0001.svg", "comp/frame_0002.exr", "bench.png"):
        assert (workdir / name).stat().st_size > 0, name
    assert "hidden-silhouette" in (workdir / "drawing" / "frame_0001.svg").read_text()


IN_README = {line for block in blocks("sh") for line in commands(block)}


def doc_commands(page: Path) -> list[str]:
    """The commands of a docs page's ```sh blocks, less those the README tests run already."""
    return [line for block in blocks("sh", page) for line in commands(block) if line not in IN_README]


DOC_PAGES = sorted(p.name for p in (ROOT / "docs").glob("*.md") if doc_commands(p))


@pytest.mark.slow
@pytest.mark.parametrize("page", DOC_PAGES)
def test_docs_commands_run_as_written(workdir, page):
    """The docs' ```sh blocks run too (```text blocks are other tools' commands, shown only)."""
    text = (ROOT / "docs" / page).read_text(encoding="utf-8")
    if "../shared/models" in text and not MODELS.exists():
        pytest.skip(f"shared models folder not found at {MODELS}")
    for line in doc_commands(ROOT / "docs" / page):
        r = run(line, workdir)
        assert r.returncode == 0, f"{page}: {line}\nexit {r.returncode}\n{r.stderr[-2000:]}"


def test_camera_file_example_is_read(tmp_path):
    """The parallel-projection frame that docs/camera-files.md shows is a valid camera file frame."""
    import json

    from strokekit import load_camera_path

    frame = json.loads(blocks("json", ROOT / "docs" / "camera-files.md")[-1])
    path = tmp_path / "cabinet.json"
    path.write_text(json.dumps({"width": 640, "height": 480, "frames": [frame]}))
    (camera,) = load_camera_path(path).cameras
    assert camera.projection == "cabinet"


def test_python_example_runs(workdir, monkeypatch):
    monkeypatch.chdir(workdir)
    (code,) = blocks("python")
    names: dict = {}
    exec(compile(code, "README.md", "exec"), names)  # noqa: S102
    assert names["strokes"].points.shape[1] == 2
    assert sorted(p.name for p in (workdir / "svg").iterdir()) == [f"frame_{n:04d}.svg" for n in (1, 2, 3, 4)]


def slug(heading: str) -> str:
    """The anchor of a Markdown heading, as MkDocs and GitHub make it."""
    s = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return re.sub(r"[\s]+", "-", s)


def test_readme_links_lead_somewhere():
    text = README.read_text(encoding="utf-8")
    links = re.findall(r"\]\(([^)\s]+)\)", text)
    assert links
    for link in links:
        if re.match(r"\w+://", link):
            continue
        path, _, anchor = link.partition("#")
        target = ROOT / path
        assert target.exists(), link
        if anchor:
            headings = re.findall(r"^#+ (.+)$", target.read_text(encoding="utf-8"), re.M)
            assert anchor in {slug(h) for h in headings}, link


def test_slug_matches_mkdocs():
    assert slug("Measuring coherence: `strokekit coherence`") == "measuring-coherence-strokekit-coherence"
    assert slug("On a cluster (dask)") == "on-a-cluster-dask"


def cli_flags() -> set[str]:
    """Every option name of every strokekit command, read from the click commands."""
    import click

    from strokekit_cli.main import cli

    flags: set[str] = set()

    def walk(cmd: click.Command, ctx: click.Context) -> None:
        for param in cmd.get_params(ctx):
            flags.update(o for o in (*param.opts, *param.secondary_opts) if o.startswith("--"))
        if isinstance(cmd, click.Group):
            for name in cmd.list_commands(ctx):
                walk(cmd.get_command(ctx, name), click.Context(cmd, info_name=name, parent=ctx))

    walk(cli, click.Context(cli, info_name="strokekit"))
    return flags


# flags of other tools the docs quote (pip, npm, dask, mkdocs); the benchmark scripts' own flags
# are read from their argparse declarations
OTHER_TOOLS_FLAGS = {"--nworkers", "--port", "--prefix", "--strict", "--no-deps"}


def benchmark_flags() -> set[str]:
    return {m for p in (ROOT / "benchmarks").glob("*.py")
            for m in re.findall(r"add_argument\(\s*\"(--[a-z0-9-]+)\"", p.read_text(encoding="utf-8"))}


def test_docs_name_real_options():
    """Every --option the README and docs/ name exists in some strokekit command (a renamed or
    removed flag fails here), apart from the other tools' flags they quote."""
    known = cli_flags()
    assert {"--kinds", "--hidden", "--exr-codec", "--no-coherence", "--up"} <= known
    unknown: dict[str, list[str]] = {}
    for p in [README, *sorted((ROOT / "docs").glob("*.md"))]:
        for flag in set(re.findall(r"(?<![\w-])--[a-z][a-z0-9-]*", p.read_text(encoding="utf-8"))):
            if flag not in known and flag not in OTHER_TOOLS_FLAGS | benchmark_flags():
                unknown.setdefault(flag, []).append(p.name)
    assert not unknown, unknown


def test_every_docs_page_is_in_the_nav():
    # mkdocs --strict (CI) refuses a page left out of the nav; this says so in seconds.
    nav = set(re.findall(r":\s*([\w./-]+\.md)\s*$", (ROOT / "mkdocs.yml").read_text(), re.M))
    pages = {p.relative_to(ROOT / "docs").as_posix() for p in (ROOT / "docs").rglob("*.md")}
    assert pages - nav == set(), "add these pages to mkdocs.yml's nav"
