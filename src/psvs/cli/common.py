"""Helpers shared by the subcommands."""
from __future__ import annotations

from pathlib import Path

from psvs.io.params import load_rig
from psvs.optics.rig import Rig, default_rig


def add_rig_argument(parser, required: bool = True) -> None:
    parser.add_argument("--rig", metavar="RIG.toml", required=required,
                        help="rig file (TOML or JSON; see docs/rig_file.md)" +
                             ("" if required else "; default: the paper's rig"))


def rig_from_args(args) -> Rig:
    return load_rig(args.rig) if args.rig else default_rig()


def check_output_path(path: str | None, suffixes: tuple[str, ...]) -> Path | None:
    """Validate an output path before any work: known suffix, existing folder."""
    if path is None:
        return None
    p = Path(path)
    if p.suffix.lower() not in suffixes:
        raise ValueError(f"output {p} must end in {' or '.join(suffixes)}")
    if not p.parent.is_dir():
        raise FileNotFoundError(f"output folder does not exist: {p.parent}")
    return p


def load_scene_spec(spec: str):
    """A scene from a scene file (TOML) or a built-in spec such as ``fig9:distance_mm=800``."""
    from psvs.io.scene_file import load_scene
    from psvs.simulate.builtin import BUILTINS, builtin_scene
    if spec.endswith(".toml") or Path(spec).exists():
        return load_scene(spec)
    if spec.partition(":")[0] in BUILTINS:
        return builtin_scene(spec)
    raise ValueError(f"scene {spec!r} is neither a scene file nor a built-in ({', '.join(BUILTINS)})")


def parse_seed(text: str | None) -> tuple[float, float] | None:
    """``--seed U,V`` as (u, v) px; None stays None; anything else is a one-line ValueError."""
    if text is None:
        return None
    try:
        u, v = (float(c) for c in text.split(","))
    except ValueError:
        raise ValueError(f"--seed must be 'u,v' in px, got {text!r}") from None
    return u, v
