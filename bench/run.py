"""Run the benchmarks (bench_*.py) and write docs/benchmarks.md with the machine and the date.

    python3 dev.py bench            # all
    python3 dev.py bench triangulate
    python3 dev.py bench --case mv1440 render match   # only the cases whose name holds "mv1440"
    python3 dev.py bench --case "mv1440|paper chain"  # ... or "paper chain" (| separates alternatives)

Each bench module defines ``cases()`` returning a list of ``(name, setup_result_fn, target_s)`` where
calling ``setup_result_fn()`` returns the zero-argument function to time (a function that returns a float
has timed itself: that many seconds, best of 7), and may define ``RATIOS``, a list of
``(name, case_a, case_b)``: the ratio of two of its cases' times, measured in the same run, and ``MEMORY``, a
dict that its cases fill with a process's peak resident memory in MiB by case name (with ``MEMORY_LIMIT_MIB``).
Time per call: the best of 7 batches of back-to-back calls (timeit's method; one call per batch for cases slower
than 50 ms).
BLAS/OpenMP are pinned to one thread; the render group uses its own thread pool (both cores).
"""
from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import datetime  # noqa: E402
import importlib.util  # noqa: E402
import platform  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
OUT = HERE.parent / "docs" / "benchmarks.md"


def machine() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return (f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}, NumPy {np.__version__}, "
            f"{platform.system()} {platform.release()}")


def time_best(fn, repeat: int = 7) -> float:
    """Seconds per call, as timeit does: calls in batches (enough for ~50 ms a batch, as a frame loop runs
    them back to back), the best batch's mean over ``repeat`` batches (the minimum: interference only ever
    adds time)."""
    t0 = time.perf_counter()
    own = fn()
    single = time.perf_counter() - t0
    if isinstance(own, float):   # a case that times itself (e.g. a child process up to a line it prints)
        return min([own] + [fn() for _ in range(repeat - 1)])
    inner = max(1, int(0.05 / max(single, 1e-6)))
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(inner):
            fn()
        best = min(best, (time.perf_counter() - t0) / inner)
    return best


def main(argv: list[str]) -> int:
    load0 = os.getloadavg()[0]
    argv = list(argv)
    case = None
    if "--case" in argv:
        k = argv.index("--case")
        case = argv[k + 1]
        del argv[k:k + 2]
    if any(a.startswith("-") for a in argv):
        print(__doc__.strip(), file=sys.stderr)       # -h, --help or an option it does not know: write nothing
        return 0 if set(argv) <= {"-h", "--help"} else 2
    modules = sorted(HERE.glob("bench_*.py"))
    if argv:
        modules = [m for m in modules if any(a in m.stem for a in argv)]
        if not modules:
            print(f"no benchmark group matches {' '.join(argv)} (groups: "
                  f"{', '.join(m.stem[6:] for m in sorted(HERE.glob('bench_*.py')))})", file=sys.stderr)
            return 2
    rows, ratios, memory = [], [], []
    stale = set()                  # ratios of which this run measured one case only
    for path in modules:
        spec = importlib.util.spec_from_file_location(path.stem, path)
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        for name, setup, target in mod.cases():
            if case is not None and not any(c in name for c in case.split("|")):
                continue
            fn = setup()
            t = time_best(fn)
            ok = "—" if target == float("inf") else ("yes" if t <= target else "NO")
            rows.append((path.stem.removeprefix("bench_"), name, t, target, ok))
            print(f"{name:<55} {t * 1e3:10.1f} ms  " + ("(reported)" if ok == "—" else
                                                           f"(target {target * 1e3:.0f} ms: {ok})"), flush=True)
        times = {r[1]: r[2] for r in rows if r[0] == path.stem.removeprefix("bench_")}
        for name, a, b in getattr(mod, "RATIOS", []):
            if (a in times) != (b in times):      # one case measured again: the old ratio was of another run
                stale.add((path.stem.removeprefix("bench_"), name))
                print(f"{name}: left out (only one of its two cases ran)", flush=True)
            if a not in times or b not in times:
                continue
            ratios.append((path.stem.removeprefix("bench_"), name, times[a] / times[b]))
            print(f"{name:<55} {ratios[-1][2]:10.2f}", flush=True)
        limit = getattr(mod, "MEMORY_LIMIT_MIB", float("inf"))
        for name, mib in getattr(mod, "MEMORY", {}).items():
            memory.append((path.stem.removeprefix("bench_"), name, mib, limit))
            print(f"{name:<55} {mib:10.0f} MiB peak", flush=True)
    if not rows:
        print(f"no case matches --case {case!r}: docs/benchmarks.md left as it was", file=sys.stderr)
        return 2
    # keep the rows of cases not run this time (python3 dev.py bench GROUP re-measures one group, --case
    # SUBSTR the cases whose name holds SUBSTR)
    ran = {r[0] for r in rows} if case is None else set()
    measured = {(r[0], r[1]) for r in rows}
    ran_ratios = {(r[0], r[1]) for r in ratios}
    ran_memory = {(r[0], r[1]) for r in memory}
    if OUT.exists():
        for line in OUT.read_text().splitlines():
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            if len(cells) == 5 and cells[0] not in ran and (cells[0], cells[1]) not in measured \
                    and cells[0] not in ("group", "---"):
                target = float("inf") if cells[3] in ("—", "inf") else float(cells[3]) / 1e3
                met = "—" if target == float("inf") else cells[4]
                rows.append((cells[0], cells[1], float(cells[2]) / 1e3, target, met))
            elif len(cells) == 3 and cells[0] not in ran and (cells[0], cells[1]) not in ran_ratios | stale \
                    and cells[0] not in ("group", "---"):
                ratios.append((cells[0], cells[1], float(cells[2])))
            elif len(cells) == 4 and cells[0] not in ran and (cells[0], cells[1]) not in ran_memory \
                    and cells[0] not in ("group", "---"):
                memory.append((cells[0], cells[1], float(cells[2]), float("inf") if cells[3] == "—" else
                               float(cells[3])))
    rows.sort(key=lambda r: r[0])
    ratios.sort(key=lambda r: r[0])
    lines = ["# Benchmarks", "",
             "Written by `python3 dev.py bench` (bench/run.py): time per call, best of 7 batches of back-to-back calls",
             "(one call a batch above 50 ms). Triangulation, projection and matching run on",
             "one thread; rendering uses both cores (its own thread pool).", "",
             f"- Date: {datetime.date.today().isoformat()}", f"- Machine: {machine()}",
             f"- The last run measured {', '.join(sorted({g for g, _ in measured})) or 'nothing'}"
             f"{'' if case is None else ' (cases matching ' + ' or '.join(map(repr, case.split('|'))) + ')'}"
             f"{'; the other rows are from earlier runs' if len(rows) > len(measured) else ''}",
             f"- Load average (1 min) at the start and the end of the last run: {load0:.1f} and "
             f"{os.getloadavg()[0]:.1f}"
             f" ({os.cpu_count()} cores; above that, other work shared them and slowed every case measured)", "",
             "| group | case | time (ms) | target (ms) | met |", "|---|---|---:|---:|---|"]
    # 3 significant digits at least (a ratio of two ms-scale cases is read back from these to 1 %)
    lines += [f"| {g} | {n} | {t * 1e3:.{1 if t >= 0.01 else 2}f} | "
              f"{'—' if tg == float('inf') else f'{tg * 1e3:.0f}'} | {ok} |" for g, n, t, tg, ok in rows]
    if ratios:
        lines += ["", "Ratios of two cases' times measured in the same run:", "",
                  "| group | ratio | value |", "|---|---|---:|"]
        lines += [f"| {g} | {n} | {v:.2f} |" for g, n, v in ratios]
    if memory:
        memory.sort(key=lambda r: r[0])
        lines += ["", "Peak resident memory of the processes measured (the largest over the calls):", "",
                  "| group | process | peak (MiB) | limit (MiB) |", "|---|---|---:|---:|"]
        lines += [f"| {g} | {n} | {m:.0f} | {'—' if lim == float('inf') else f'{lim:.0f}'} |"
                  for g, n, m, lim in memory]
    OUT.write_text("\n".join(lines) + "\n")
    print(f"wrote {OUT}")
    return 0 if all(r[4] in ("yes", "—") for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
