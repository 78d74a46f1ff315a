"""``psvs batch disparity|match|measure INPUT --rig RIG -o DIR``: one command over every frame of a folder of
images, an image sequence or a video, as tasks on a Dask cluster (:mod:`psvs.cluster`), resumably.

Each frame's result is the file the single command writes (``psvs disparity``'s map, ``psvs match``'s JSON,
``psvs measure --json``'s JSON), named after the frame in DIR; a row per frame (its status and the summary's
figures) streams into ``DIR/results.parquet``. A task gets the frame's name or index, never its pixels: the
worker reads the frame itself. A frame the command answers in one line (cannot measure, bad input) is a row
with that line; a second run over DIR computes only the frames without a row (docs/cluster.md)."""
from __future__ import annotations

import argparse
import functools
import hashlib
import importlib
import json
import shutil
import sys
import threading
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

#: The commands batch runs: (module, the suffix of its -o file, its other outputs: written per frame as
#: DIR/<frame>.<the name given>, the options batch cannot give per frame).
COMMANDS = {
    "disparity": ("disparity_cmd", ".npy", ("right", "confidence", "views", "depth", "cloud"), ()),
    "match": ("match_cmd", ".json", ("csv", "ply"), ("figures",)),
    "measure": ("measure_cmd", ".json", (), ()),
}
#: What batch adds to a command's arguments (not passed to the command).
_OWN = ("command", "batch_command", "run", "scheduler", "workers", "image", "output")
_PSVS_DIR = str(Path(__file__).resolve().parents[1])
_WORKER = threading.local()          # what a worker thread keeps between its frames (:func:`_workspace`)


def add_parser(sub) -> None:
    p = sub.add_parser("batch", help="run disparity, match or measure over a folder, sequence or video on Dask",
                       description="Run `psvs disparity`, `psvs match` or `psvs measure` over every frame of a "
                                   "folder of images, an image sequence (seq_%%03d.png) or a video, as tasks on a "
                                   "Dask cluster: a local one on this machine's cores, or --scheduler "
                                   "tcp://HOST:8786 (docs/cluster.md). Each frame's result is the file the single "
                                   "command writes, named after the frame in DIR (frame_000012.npy, or the "
                                   "image's name); a row per frame goes to DIR/results.parquet as it finishes. "
                                   "A second run over DIR computes only what is missing (and a frame whose files "
                                   "no longer read back: deleted, cut short or written over since). The command's "
                                   "options "
                                   "follow it (e.g. psvs batch match run.avi --rig default -o out --auto); its "
                                   "other outputs (--right R.npy, --csv M.csv, ...) are written per frame as "
                                   "DIR/<frame>.<the name given>.")
    inner = p.add_subparsers(dest="batch_command", metavar="COMMAND", parser_class=type(p), required=True)
    for name, (module, suffix, _, _) in COMMANDS.items():
        importlib.import_module(f"psvs.cli.{module}").add_parser(inner)
        q = inner.choices[name]
        q.description = (f"psvs {name} on every frame of INPUT, as tasks on Dask (psvs batch --help); one result per "
                         f"frame in DIR, resumable. What psvs {name} does: {q.description}")
        for action in q._actions:
            if action.dest == "image":
                action.metavar, action.help = "INPUT", "a folder of images, a sequence (seq_%%03d.png) or a video"
            elif action.dest == "output":
                action.metavar, action.help = "DIR", f"folder of the results: one {suffix} per frame, results.parquet"
        if name == "measure":      # a measurement's JSON is its result here: written per frame, not printed
            q.add_argument("-o", "--output", metavar="DIR", required=True,
                           help="folder of the results: one .json per frame (as --json prints), results.parquet")
        q.add_argument("--scheduler", metavar="ADDR", help="an existing Dask scheduler, tcp://HOST:8786 (default: a "
                                                           "local cluster on this machine's cores)")
        q.add_argument("--workers", type=int, metavar="N", help="local cluster: worker processes (default: the "
                                                                "cores)")
        q.set_defaults(run=run)


@dataclass(frozen=True)
class Frames:
    """The frames of INPUT: a video's (``keys`` frame_000000, ...) or image files' (``keys`` their names in
    ``folder``)."""

    source: str
    video: bool
    keys: tuple
    folder: str = ""
    size_px: tuple | None = None


def list_frames(text: str) -> Frames:
    """The frames of a folder of images, a printf sequence or a video file; one-line errors when none."""
    from psvs.io.video import video_frames
    from psvs.live.source import SEQUENCE_SUFFIXES, sequence_files
    path = Path(text)
    if path.is_dir() or "%" in text:
        files = sequence_files(text)
        if not files:
            raise FileNotFoundError(f"no image ({', '.join(SEQUENCE_SUFFIXES)}) in {text}")
        stems = [f.stem for f in files]
        twin = next((s for s in stems if stems.count(s) > 1), None)
        if twin is not None:
            raise ValueError(f"{text}: two images named {twin} (their results would share one file)")
        return Frames(str(path.resolve()), False, tuple(f.name for f in files), str(files[0].parent.resolve()))
    if path.suffix.lower() in SEQUENCE_SUFFIXES:
        raise ValueError(f"INPUT {text} is one image: give a folder of images, a sequence (seq_%03d.png) or a video "
                         "(or run the command itself)")
    n, size = video_frames(path)
    digits = max(6, len(str(n - 1)))
    return Frames(str(path.resolve()), True, tuple(f"frame_{i:0{digits}d}" for i in range(n)), size_px=size)


def _job(args, frames: Frames, out_dir: Path) -> dict:
    """What every task needs: the command, its arguments (input paths absolute), the frames' source, DIR."""
    cmd = args.batch_command
    _, _, per_frame, refused = COMMANDS[cmd]
    given = {k: v for k, v in vars(args).items() if k not in _OWN}
    bad = next((k for k in refused if given.get(k) is not None), None)
    if bad is not None:
        raise ValueError(f"--{bad} cannot be given per frame in psvs batch; run psvs {cmd} on the frames it is for")
    for k in ("rig", "pipeline"):
        if given.get(k) is not None and Path(given[k]).exists():
            given[k] = str(Path(given[k]).resolve())
    return {"command": cmd, "args": given, "per_frame": [k for k in per_frame if given.get(k) is not None],
            "source": frames.source, "video": frames.video, "folder": frames.folder, "out_dir": str(out_dir)}


#: The run folder's own files (psvs.cluster.store): no frame's result may take one of these names.
RUN_FILES = frozenset({"study.json", "results.parquet", "parts"})


def frame_args(job: dict, key: str) -> argparse.Namespace:
    """The single command's arguments for one frame: its image (the video for a video's frame) and its
    outputs in DIR named after the frame."""
    _, suffix, _, _ = COMMANDS[job["command"]]
    out_dir, stem = Path(job["out_dir"]), Path(key).stem if not job["video"] else key
    args = dict(job["args"])
    for k in job["per_frame"]:
        v = args[k]
        args[k] = [str(out_dir / f"{stem}.{Path(x).name}") for x in v] if isinstance(v, list) else \
            str(out_dir / f"{stem}.{Path(v).name}")
    args.update(image=job["source"] if job["video"] else str(Path(job["folder"]) / key),
                output=str(out_dir / f"{stem}{suffix}"))
    return argparse.Namespace(**args)


def frame_outputs(job: dict, key: str) -> list[str]:
    """Every file one frame writes (its output and its per-frame files), as :func:`frame_args` names them."""
    a = frame_args(job, key)
    named = [a.output, *(getattr(a, k) for k in job["per_frame"])]
    return [x for v in named for x in (v if isinstance(v, list) else [v])]


def _frame_index(job: dict, key: str) -> int:
    return int(key.rsplit("_", 1)[1]) if job["video"] else -1


def _workspace():
    """This worker thread's dense workspace (psvs.dense.workspace): its cost volumes kept from one frame to
    the next, as a live loop keeps them (fresh memory costs page faults on every frame: a quarter of a
    640x480 map's time). It holds the largest frame's volumes until the worker closes."""
    from psvs.dense.workspace import Workspace
    ws = getattr(_WORKER, "workspace", None)
    if ws is None:
        ws = _WORKER.workspace = Workspace()
    return ws


def _compute(job: dict, args, image) -> dict:
    """The command on one frame: its files written, its summary as a row."""
    module = importlib.import_module(f"psvs.cli.{COMMANDS[job['command']][0]}")
    if job["command"] == "disparity":
        _, dense, trust, _ = module.compute(args, image, _workspace())
        return module.summary_row(dense, trust)
    if job["command"] == "match":
        return module.summary_row(module.compute(args, image))
    from psvs.io.atomic import write_atomic
    m = module.compute(args, image)
    write_atomic(args.output, json.dumps(m.to_dict()) + "\n")        # what `psvs measure --json` prints
    return {"Z_mm": m.Z_mm, "diameter_mm": m.diameter_mm, "first_last_distance_mm": m.first_last_distance_mm}


def frame_task(job: dict, key: str) -> dict:
    """What a worker runs for one frame: read it, run the command, a row (``status`` ok, cannot measure or bad
    input, with the one line the command would print; psvs's warnings; the summary's figures)."""
    from psvs._quiet import quiet_libraries
    from psvs.errors import MeasurementError, RigGeometryError
    args = frame_args(job, key)
    row = {"output": Path(args.output).name, "status": "ok", "message": ""}
    with quiet_libraries("psvs batch"), warnings.catch_warnings(record=True) as caught:
        try:
            image = None
            if job["video"]:
                from psvs.io.video import read_video_frame
                image = read_video_frame(job["source"], _frame_index(job, key))
            row.update(_compute(job, args, image))
        except MeasurementError as exc:
            row.update(status="cannot measure", message=_line(exc))
        except (ValueError, TypeError, OSError, RigGeometryError) as exc:
            row.update(status="bad input", message=_line(exc))
    said = [str(w.message) for w in caught if str(w.filename).startswith(_PSVS_DIR)]
    row["warnings"] = "; ".join(dict.fromkeys(said))
    if row["status"] == "ok":
        from psvs.cli.batch_resume import files_digest
        row["files_sha256"] = files_digest(frame_outputs(job, key))
    return row


def _line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def _input_digest(frames: Frames) -> str:
    """A digest of what the input holds now: each frame file's name, size and modification time (the video
    file's, for a video). A video recorded again under the same name, or an image replaced in the folder, is
    another input: a run folder made from the old one kept its maps and counted them as this input's (an
    adversarial trial), so it is refused instead."""
    paths = [Path(frames.source)] if frames.video else [Path(frames.folder) / k for k in frames.keys]
    h = hashlib.sha256()
    for p in paths:
        try:
            st = p.stat()
            h.update(f"{p.name}\0{st.st_size}\0{st.st_mtime_ns}\n".encode())
        except OSError:             # a dangling link named as a frame: its frame is refused by its reader
            h.update(f"{p.name}\0missing\n".encode())
    return h.hexdigest()


def _params(job: dict, frames: Frames) -> dict:
    """What makes a frame's result what it is (DIR/study.json): the command, its options, the input (its
    path and :func:`_input_digest`), and the rig file's and pipeline file's contents."""
    from psvs.io.params import rig_path
    files = {"rig": rig_path(job["args"]["rig"])}
    if job["args"].get("pipeline"):
        files["pipeline"] = Path(job["args"]["pipeline"])
    digests = {f"{k}_sha256": hashlib.sha256(p.read_bytes()).hexdigest() for k, p in files.items() if p.is_file()}
    return {"command": job["command"], "input": job["source"], "input_files_sha256": _input_digest(frames),
            "options": job["args"], **digests}


def _preflight(job: dict, frames: Frames) -> None:
    """The command's own checks of its arguments (on a blank frame of the rig's size), before any work: a bad
    option is refused in one line with nothing written, not once per frame."""
    from psvs.io.params import load_rig
    rig = load_rig(job["args"]["rig"])
    w, h = rig.camera.image_size_px
    if frames.video and tuple(frames.size_px) != (w, h):
        fw, fh = frames.size_px
        raise ValueError(f"{frames.source}: frames are {fw}x{fh} px but the rig's camera is {w}x{h} px")
    for key in frames.keys:                  # a frame's output named as the run's own files would replace them
        clash = sorted({Path(x).name for x in frame_outputs(job, key)} & RUN_FILES)
        if clash:
            raise ValueError(f"frame {key}: its result would be named {clash[0]}, as the run's own file in "
                             f"{job['out_dir']}: rename that frame")
    args = frame_args(job, frames.keys[0])
    module = importlib.import_module(f"psvs.cli.{COMMANDS[job['command']][0]}")
    module.prepare(args, np.zeros((h, w), np.uint8))


def _out_dir(text: str) -> Path:
    from psvs.cluster.store import check_run_folder
    return check_run_folder(text, "psvs batch")


def _recompute_damaged(job: dict, out_dir: Path) -> None:
    """Frames stored as done whose files no longer read back (psvs.cli.batch_resume) are forgotten, so this
    run computes them again, and said in one line."""
    from psvs.cli.batch_resume import damaged_results
    from psvs.cluster import ResultStore
    store = ResultStore(out_dir)
    damaged = damaged_results(job, store.read(), frame_outputs)
    if damaged:
        store.forget(damaged)
        key, why = next(iter(damaged.items()))
        print(f"psvs batch: {len(damaged)} frame(s)' results no longer read back and are computed again "
              f"({key}: {why})", file=sys.stderr)


def run(args) -> int:
    from psvs.cluster import RunOptions, connect, read_results, run_tasks, task_threads
    from psvs.cluster.store import check_params
    if args.rig is None:
        raise ValueError("psvs batch needs --rig (the frames' camera and the disparity range)")
    out_dir = _out_dir(args.output)
    frames = list_frames(args.image)
    if not frames.video and out_dir == Path(frames.folder):
        raise ValueError(f"-o {args.output} is the folder of the images: give another (a result there could be "
                         "read as a frame by the next run)")
    job = _job(args, frames, out_dir)
    created = not out_dir.exists()
    out_dir.mkdir(exist_ok=True)         # the command's own checks want its outputs' folder
    try:
        _preflight(job, frames)
        params = _params(job, frames)     # stats every frame once: the input as it is now
        check_params(out_dir, params)
        if job["command"] == "disparity":       # the workers compile them, once each (psvs.dense.compiled)
            from psvs.dense.compiled import announce_dense
            announce_dense("psvs batch disparity")
        client = connect(args.scheduler, args.workers)
    except BaseException:
        if created:                      # refused: nothing left behind
            shutil.rmtree(out_dir, ignore_errors=True)
        raise
    with client:
        _recompute_damaged(job, out_dir)
        summary = run_tasks(client, functools.partial(frame_task, job), frames.keys, out_dir, params,
                            RunOptions(label=f"psvs batch {job['command']}", threads=task_threads(client)))
    status = read_results(out_dir).column("status").to_pylist()
    counts = {s: status.count(s) for s in ("ok", "cannot measure", "bad input") if status.count(s)}
    print(f"{out_dir}: {len(frames.keys)} frames, " + ", ".join(f"{n} {s}" for s, n in counts.items())
          + f" ({summary.computed} computed now, {summary.skipped} before; rows in results.parquet)")
    if summary.failed:
        key, reason = next(iter(summary.failed.items()))
        print(f"psvs batch: {len(summary.failed)} frame(s) failed and were not written (a second run tries them "
              f"again); {key}: {reason}", file=sys.stderr)
        return 1
    if status and "ok" not in counts:     # every frame refused: the folder holds no result
        first = next(m for m in read_results(out_dir).column("message").to_pylist() if m)
        print(f"psvs batch: no frame gave a result; the first said: {first}", file=sys.stderr)
        return 1
    return 0
