"""``psvs rig``: the rig files shipped with psvs (``list``), and any rig as TOML (``show``)."""
from __future__ import annotations

from pathlib import Path

from psvs.io.params import load_rig, rig_path, rig_to_dict
from psvs.io.tomlfile import dumps_toml
from psvs.rigs import SHIPPED


def add_parser(sub) -> None:
    p = sub.add_parser("rig", help="list the shipped rigs, or print a rig file (e.g. psvs rig show default)",
                       description="`psvs rig list` names the rigs shipped with psvs (usable as --rig NAME); "
                                   "`psvs rig show NAME|FILE` prints a rig as TOML: a shipped rig with its "
                                   "comments, a file as psvs reads it (every key, degrees).")
    p.add_argument("action", choices=("list", "show"))
    p.add_argument("rig", nargs="?", metavar="NAME|FILE", help="for show: a shipped rig's name or a rig file")
    p.set_defaults(run=run)


def run(args) -> int:
    if args.action == "list":
        if args.rig is not None:
            raise ValueError("psvs rig list takes no rig")
        for name in SHIPPED:
            rig = load_rig(name)
            m = rig.mirrors
            kind = "as designed" if rig.as_designed else "a misaligned build"
            print(f"{name:<18} f {rig.camera.focal_length_mm:g} mm, b {m.baseline_mm:g} mm, M1 at "
                  f"{m.m1_axis_distance_mm:g} mm, M2 at {m.m2_axis_distance_mm:g} mm, {kind}")
        return 0
    if args.rig is None:
        raise ValueError("psvs rig show needs a shipped rig's name or a rig file")
    path = rig_path(args.rig)
    if path != Path(args.rig):   # a shipped rig: its file as written, with the comments
        print(path.read_text(encoding="utf-8"), end="")
    else:
        print(dumps_toml(rig_to_dict(load_rig(path))), end="")
    return 0
