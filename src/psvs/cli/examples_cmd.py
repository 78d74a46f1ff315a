"""``psvs examples``: write the example files shipped with psvs (the README's commands read them)."""
from __future__ import annotations

from pathlib import Path

from psvs.examples import example_files
from psvs.io.atomic import output_batch, write_atomic


def add_parser(sub) -> None:
    p = sub.add_parser("examples", help="write the example files the README's commands read into a folder",
                       description="Write psvs's example files (matches.csv, known_points.csv, scenes/desk.toml "
                                   "with its assets, tolerances_small.toml, ...) into DIR, so the README's "
                                   "commands run from a pip install. A file already there with other contents "
                                   "is never overwritten: the command refuses and writes nothing.")
    p.add_argument("-o", "--output", required=True, type=Path, metavar="DIR", help="folder to write them into")
    p.set_defaults(run=run)


def run(args) -> int:
    out: Path = args.output
    if out.exists() and not out.is_dir():
        raise ValueError(f"{out} is a file, not a folder")
    files = example_files()
    todo = {}
    for name, src in files.items():
        data, dest = src.read_bytes(), out / name
        if dest.is_dir():
            raise ValueError(f"{dest} is a folder where the example file goes: not replaced (nothing written)")
        if dest.exists() and dest.read_bytes() != data:
            raise ValueError(f"{dest} exists with other contents: not overwritten (nothing written)")
        if not dest.exists():
            todo[dest] = data
    with output_batch():
        for dest, data in todo.items():
            dest.parent.mkdir(parents=True, exist_ok=True)
            write_atomic(dest, data)
    print(f"{len(todo)} example file(s) written to {out} ({len(files) - len(todo)} already there)")
    return 0
