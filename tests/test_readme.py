"""Every CLI example in the README (and in docs/*.md, one scratch folder per file) runs, in order, in one
scratch folder with a copy of examples/ (a later example may read what an earlier one wrote, as in a shell
session). ``psvs serve`` runs until stopped: it is
started as a process on a free port, must answer its page and API, and is then stopped."""
import json
import re
import shlex
import shutil
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import pytest

from psvs.cli.main import main
from tests.support.web import free_port

ROOT = Path(__file__).resolve().parents[1]


def examples(path: Path) -> list[str]:
    """The ``$ psvs ...`` and ``$ mkdir -p ...`` lines of a Markdown file, in order, without the ``$ ``."""
    return [line[2:] for line in re.findall(r"^\$ (?:psvs|mkdir -p) .*$", path.read_text(), re.M)]


EXAMPLES = examples(ROOT / "README.md")
DOCS_WITH_EXAMPLES = [p for p in sorted((ROOT / "docs").glob("*.md")) if examples(p)]


def test_readme_has_examples():
    assert len(EXAMPLES) >= 4


def run_server(args, cwd: Path) -> None:
    """Start ``psvs serve ARGS`` on a free port, check it answers, stop it."""
    port = free_port()
    if "--port" in args:
        i = args.index("--port")
        args = args[:i] + args[i + 2:]
    proc = subprocess.Popen([sys.executable, "-m", "psvs", *args, "--port", str(port)], cwd=cwd,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        t0 = time.monotonic()
        while True:
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() - t0 < 60, "psvs serve did not answer within 60 s"
            try:
                with urllib.request.urlopen(f"http://127.0.0.1:{port}/api/info", timeout=5) as r:
                    info = json.load(r)
                break
            except OSError:
                time.sleep(0.2)
        assert info["image_size_px"] == [640, 480]
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=5) as r:
            assert b'<canvas id="image"' in r.read()
    finally:
        proc.terminate()
        out, err = proc.communicate(timeout=30)
    assert f"open http://127.0.0.1:{port}/" in out and "error" not in err, (out, err)


@pytest.mark.slow          # every CLI example: the lock suite runs it; .ci/latest runs psvs demo from the wheel
def test_readme_examples_run_in_order(tmp_path, monkeypatch, capsys):
    run_examples(EXAMPLES, tmp_path, monkeypatch, capsys)
    # every output lands in out/ (git-ignored), none in the folder the user runs from
    assert sorted(p.name for p in tmp_path.iterdir()) == ["examples", "out"]
    assert (tmp_path / "out" / "demo").is_dir() and (tmp_path / "out" / "fig5b_match.json").is_file()


@pytest.mark.slow
def test_docs_examples_run_in_order(tmp_path, monkeypatch, capsys):
    assert DOCS_WITH_EXAMPLES, "no docs/*.md has a $ psvs example"
    for doc in DOCS_WITH_EXAMPLES:
        folder = tmp_path / doc.stem
        folder.mkdir()
        run_examples(examples(doc), folder, monkeypatch, capsys)


def run_examples(lines, tmp_path: Path, monkeypatch, capsys) -> None:
    shutil.copytree(ROOT / "examples", tmp_path / "examples")
    monkeypatch.chdir(tmp_path)
    for line in lines:
        words = shlex.split(line)
        if words[0] == "mkdir":
            for folder in words[2:]:
                (tmp_path / folder).mkdir(parents=True, exist_ok=True)
            continue
        args = words[1:]
        if args[0] == "serve":
            run_server(args, tmp_path)
            continue
        code = main(args)
        err = capsys.readouterr().err
        assert "error" not in err, (line, err)
        assert code == 0, line   # the default rig is a clear layout: `design` exits 0 (1 only when blocked)
        for i, a in enumerate(args):
            if a == "-o":
                assert (tmp_path / args[i + 1]).stat().st_size > 0, line
