"""Run every switchest benchmark and write ``benchmarks/results.md``.

All measurements run with BLAS limited to one thread (threadpoolctl); the file
records the machine (CPU count, load average before and after each benchmark,
NumPy / SciPy versions, BLAS libraries and their threads) next to one markdown
table per benchmark.

Run: ``python benchmarks/run_all.py [--quick]`` (about two minutes in full on
two cores, a third of it FilterPy's loop over 500 trials).
"""

from __future__ import annotations

import argparse
import datetime
import os
import subprocess
import time
from pathlib import Path

import bench_engine
import bench_imm
import bench_imm_ev1
import bench_simulate
from harness import (
    format_seconds,
    machine_info,
    markdown_table,
    print_sections,
    single_threaded_blas,
)

HERE = Path(__file__).resolve().parent
BENCHMARKS = [
    ("IMM vs FilterPy", bench_imm),
    ("IMM engine vs a plain scalar numba IMM", bench_engine),
    ("IMM-EV1 scaling", bench_imm_ev1),
    ("Simulation", bench_simulate),
]


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


def _machine_section(info: dict, blas: dict, loads: list[tuple[str, str, str, str]], quick: bool) -> str:
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
        f"- Python {info['python']}, NumPy {info['numpy']}, SciPy {info['scipy']}; {info['platform']}",
        f"- switchest source: {_source_revision()}",
        ("- BLAS limited to one thread with `threadpoolctl.threadpool_limits(1)`: "
         f"**{'yes' if blas['single_threaded'] else 'NO'}**"),
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
    parser.add_argument("--output", type=Path, default=HERE / "results.md", help="markdown file to write")
    args = parser.parse_args(argv)

    info = machine_info()
    loads, body = [], []
    with single_threaded_blas() as blas:
        print(f"BLAS limited to one thread: {blas['single_threaded']}", flush=True)
        for title, module in BENCHMARKS:
            before = _load()
            start = time.perf_counter()
            sections = module.run(quick=args.quick)
            elapsed = time.perf_counter() - start
            loads.append((title, before, _load(), format_seconds(elapsed)))
            print_sections(sections)
            body.append(f"## {title}\n\n" + "\n".join(s.markdown() for s in sections))

    stamp = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC")
    header = (f"# switchest benchmark results\n\nWritten by `benchmarks/run_all.py` on {stamp}. "
              "Timings are wall-clock bests of repeated runs (`time.perf_counter`); see "
              "`benchmarks/README.md` for what each benchmark measures.\n")
    text = "\n".join([header, _machine_section(info, blas, loads, args.quick), *body])
    args.output.write_text(text)
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
