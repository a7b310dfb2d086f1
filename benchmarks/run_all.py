"""Run every switchest benchmark and write ``benchmarks/results.md``.

All measurements run with BLAS limited to one thread (threadpoolctl) and switchest's engine at
one thread (``set_threads(1)``; ``bench_engine.py``'s thread-scaling table sets two for its
second contender). Comparisons of contenders (switchest vs FilterPy, vs dynamax, vs a numba
yardstick; refine vs grid; few vs many trials) are interleaved by CPU time
(``harness.compare_interleaved``); the sweeps of one implementation (IMM-EV1 scaling,
simulation) keep the best wall time of repeats. The file records the machine (CPU count, load
average before and after each benchmark, NumPy / SciPy and peer library versions, BLAS
libraries and their threads, the engine's default threads) next to the markdown tables of
every benchmark.

Run: ``python benchmarks/run_all.py [--quick] [--reference PYTHON --reference-path SRC]``
(several minutes in full on two cores; ``--quick`` is a smoke run of about three minutes). With
a reference installation, ``bench_versus.py`` also runs (this checkout against it, workload by
workload); without one it is skipped.
"""

from __future__ import annotations

import argparse
import datetime
import os
import subprocess
import sys
import time
import traceback
from pathlib import Path

import bench_engine
import bench_imm
import bench_imm_ev1
import bench_learn
import bench_mode_kalman
import bench_multiple_model
import bench_reproduce
import bench_simulate
import bench_startup
import bench_switch_time
import bench_versus
from harness import (
    Section,
    format_seconds,
    machine_info,
    markdown_table,
    print_sections,
    single_threaded,
)

HERE = Path(__file__).resolve().parent
BENCHMARKS = [
    ("IMM vs FilterPy", bench_imm),
    ("IMM engine vs a plain scalar numba IMM", bench_engine),
    ("Kalman filter vs dynamax", bench_mode_kalman),
    ("Switching-time estimation: refine vs grid", bench_switch_time),
    ("Multiple-model filters: GPB, smoothing, particles against the exact posterior",
     bench_multiple_model),
    ("IMM-EV1 scaling", bench_imm_ev1),
    ("Learning: EM error against the data size", bench_learn),
    ("Simulation", bench_simulate),
    ("Paper reproductions at full size", bench_reproduce),
    ("Start-up of a process that filters", bench_startup),
    ("This checkout against a reference installation", bench_versus),
]
NEEDS_REFERENCE = {bench_versus}


def _source_revision() -> str:
    """The repository's HEAD and whether the package sources differ from it (read-only git)."""
    def git(*args):
        return subprocess.run(["git", *args], cwd=HERE.parent, capture_output=True, text=True,
                              check=False).stdout.strip()

    head = git("rev-parse", "--short", "HEAD") or "unknown"
    dirty = git("status", "--porcelain", "--", "src")
    return f"{head}{' + uncommitted changes in src/' if dirty else ''}"


def _load() -> str:
    return ", ".join(f"{v:.2f}" for v in os.getloadavg())


def _machine_section(info: dict, blas: dict, loads: list[tuple[str, str, str, str]],
                     quick: bool) -> str:
    libs = markdown_table(
        ["library", "API", "version", "threads by default", "threads during the runs"],
        [(b["library"], b["api"], b["version"], b["threads"], i["threads"])
         for b, i in zip(blas["before"], blas["inside"])],
    )
    lines = [
        "## Machine",
        "",
        (f"- CPU: {info['cpu']}; `os.cpu_count()` = {info['cpu_count']}, usable by this process: "
         f"{info['usable_cpus']}"),
        (f"- Python {info['python']}, NumPy {info['numpy']}, SciPy {info['scipy']}; "
         f"{info['platform']}"),
        "- peers and compilers: " + ", ".join(f"{k} {v}" for k, v in info["peers"].items()),
        f"- switchest source: {_source_revision()}",
        ("- BLAS limited to one thread with `threadpoolctl.threadpool_limits(1)` and "
         "switchest's engine at one thread (`set_threads(1)`; by default it takes "
         f"{info['engine_threads_default']}"
         + (f", SWITCHEST_THREADS={info['SWITCHEST_THREADS']}" if info["SWITCHEST_THREADS"]
            else "")
         + f"): **{'yes' if blas['single_threaded'] else 'NO'}**"),
        f"- mode: {'--quick (reduced sizes)' if quick else 'full'}",
        "",
        libs,
        "",
        ("Load average (1, 5, 15 min; `os.getloadavg()`) — the machine is shared, a load above "
         f"{info['usable_cpus']} means the benchmarks competed for the cores:"),
        "",
        markdown_table(["benchmark", "load before", "load after", "wall time"], loads),
        "",
    ]
    return "\n".join(lines)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="reduced sizes for a smoke run")
    parser.add_argument("--output", type=Path, default=HERE / "results.md",
                        help="markdown file to write")
    parser.add_argument("--reference", help="python interpreter of a reference installation "
                        "for bench_versus.py (skipped without one)")
    parser.add_argument("--reference-path", type=Path,
                        help="directory put first on the reference's path (its src/)")
    args = parser.parse_args(argv)
    if (args.reference is None) != (args.reference_path is None):
        parser.error("--reference and --reference-path go together")

    info = machine_info()
    loads, body, failed = [], [], []
    with single_threaded() as blas:
        print(f"BLAS and engine at one thread: {blas['single_threaded']}", flush=True)
        for title, module in BENCHMARKS:
            kwargs = {}
            if module in NEEDS_REFERENCE:
                if args.reference is None:
                    print(f"{title}: skipped (no --reference given)", flush=True)
                    continue
                kwargs = {"reference": args.reference, "reference_path": args.reference_path}
            before = _load()
            start = time.perf_counter()
            try:
                sections = module.run(quick=args.quick, **kwargs)
            except Exception as exc:  # noqa: BLE001 - report it, run the rest, exit non-zero
                traceback.print_exc()
                failed.append(title)
                sections = [Section(f"{title}: FAILED", markdown_table(
                    ["exception"], [[f"`{type(exc).__name__}: {exc}`"]]))]
            elapsed = time.perf_counter() - start
            loads.append((title, before, _load(), format_seconds(elapsed)))
            print_sections(sections)
            body.append(f"## {title}\n\n" + "\n".join(s.markdown() for s in sections))

    stamp = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC")
    header = (f"# switchest benchmark results\n\nWritten by `benchmarks/run_all.py` on {stamp}. "
              "Comparisons of contenders are interleaved rounds timed by CPU time "
              "(`time.process_time`; median and min, ratios of medians and of mins, with the "
              "load average); the IMM-EV1 and simulation sweeps are wall-clock bests of "
              "repeats (`time.perf_counter`). See `benchmarks/README.md` for what each "
              "benchmark measures.\n")
    text = "\n".join([header, _machine_section(info, blas, loads, args.quick), *body])
    args.output.write_text(text)
    print(f"wrote {args.output}")
    if failed:
        sys.exit(f"benchmarks that raised: {', '.join(failed)}")


if __name__ == "__main__":
    main()
