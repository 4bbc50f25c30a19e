"""A 100-variant design sweep: ``quadnodes sweep`` on Dask against a loop of ``quadnodes run --set``.

Backs docs/graphs.md "Sweeps: many variants on Dask" (its speed table) and the README's sweep figure.

Input: ``examples/quickstart.toml`` (wavy sheet sampled 22 × 41, zigzag noise, the thesis's fairing,
Laplacian and Taubin baselines, metrics, STEP assembly, OBJ, CSV schedule, two PNGs, the HTML view),
10 weights (``fair.weight=0.1:1:10``) × 10 seeds (``noisy.seed=1:10``) = 100 variants.

Peers, measured in the same run, one after the other, each from a cold start with an empty cache:

- **sweep**: one ``quadnodes sweep`` process, embedded cluster of ``--workers`` processes × 1 thread
  (default 2, the cores of this machine). The surface and sampling run once, the noise and both baselines
  and their metrics once per seed; only the fairing and what depends on it run per variant.
- **loop**: ``quadnodes run --set fair.weight=W --set noisy.seed=S --out DIR --no-cache`` for every
  variant, one process after the other (what a shell loop does): every run starts Python, imports
  build123d and matplotlib, and rebuilds the whole graph.

Wall time of each, including process and cluster start-up. ``--loop-runs K`` times only K of the 100 loop
runs (evenly spread) and scales to 100 — the table then says "estimated". The OBJ of every variant that
both produced is compared byte for byte.

Run:  python benchmarks/perf/bench_sweep.py [--workers 2] [--loop-runs 100] [--out DIR]
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
GRAPH = ROOT / "examples" / "quickstart.toml"
CLI = ["-c", "import sys; from quadnodes.cli import main; sys.exit(main())"]
WEIGHTS = [round(0.1 * k, 1) for k in range(1, 11)]
SEEDS = list(range(1, 11))


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT)] + ([env["PYTHONPATH"]] if env.get("PYTHONPATH") else []))
    return env


def _load() -> str:
    try:
        return " ".join(f"{x:.1f}" for x in os.getloadavg())
    except OSError:
        return "?"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--loop-runs", type=int, default=100, help="loop runs to time (scaled to 100)")
    ap.add_argument("--out", help="folder for the outputs (default: a temporary folder, deleted)")
    args = ap.parse_args()
    tmp = tempfile.TemporaryDirectory() if args.out is None else None
    base = Path(args.out) if args.out else Path(tmp.name)
    env = _env()
    load_before = _load()

    sweep_out = base / "sweep"
    cmd = [sys.executable, *CLI, "sweep", str(GRAPH), "--vary", "fair.weight=" + ",".join(map(str, WEIGHTS)),
           "--vary", "noisy.seed=1:10", "--out", str(sweep_out), "--workers", str(args.workers)]
    print("sweep:", " ".join(cmd[3:]), flush=True)
    t = time.perf_counter()
    done = subprocess.run(cmd, env=env, capture_output=True, text=True)
    t_sweep = time.perf_counter() - t
    if done.returncode != 0:
        sys.exit(f"sweep failed:\n{done.stdout}\n{done.stderr}")
    print(done.stdout.splitlines()[-5], flush=True)
    import csv

    with open(sweep_out / "sweep.csv", newline="") as f:
        bad = [r for r in csv.DictReader(f) if r["status"] != "ok"]
    for r in bad:  # a variant that fails fails in the loop too; both peers still do the same work
        print(f"  variant {r['folder']} failed: {r['error']}", flush=True)

    variants = [(w, s) for w in WEIGHTS for s in SEEDS]
    k = max(1, min(args.loop_runs, len(variants)))
    picked = [variants[round(i * (len(variants) - 1) / max(k - 1, 1))] for i in range(k)] if k < 100 else variants
    times, same, compared = [], 0, 0
    for i, (w, s) in enumerate(picked):
        one = base / "loop" / f"w{w}_s{s}"
        cmd = [sys.executable, *CLI, "run", str(GRAPH), "--set", f"fair.weight={w}", "--set", f"noisy.seed={s}",
               "--out", str(one), "--no-cache"]
        t = time.perf_counter()
        r = subprocess.run(cmd, env=env, capture_output=True, text=True)
        times.append(time.perf_counter() - t)
        swept = sweep_out / f"fair.weight={w}__noisy.seed={s}" / "faired.obj"
        if r.returncode == 0 and swept.exists():
            same += swept.read_bytes() == (one / "faired.obj").read_bytes()
            compared += 1
        print(f"  loop {i + 1}/{k}: {times[-1]:.1f} s", flush=True)
    t_loop = sum(times) * len(variants) / k
    estimated = "" if k == len(variants) else f" (estimated from {k} runs)"

    print()
    print(f"machine: {platform.node()}, {os.cpu_count()} cores, Python {platform.python_version()}; "
          f"load average before / after: {load_before} / {_load()} (shared with other developers)")
    print(f"input: {GRAPH.relative_to(ROOT)}, 10 weights x 10 seeds = 100 variants, cold caches")
    print()
    print("| 100 variants of the quick-start | wall time (s) | per variant (s) | vs loop |")
    print("|---|---:|---:|---:|")
    print(f"| loop of `quadnodes run --set`, one process per variant{estimated} | {t_loop:.0f} | "
          f"{t_loop / 100:.2f} | 1.00 |")
    print(f"| `quadnodes sweep`, embedded cluster, {args.workers} workers x 1 thread | {t_sweep:.0f} | "
          f"{t_sweep / 100:.2f} | {t_sweep / t_loop:.2f} |")
    print()
    print(f"faired.obj byte-equal between sweep and loop: {same} of {compared} variants compared "
          f"({len(bad)} variants failed in the sweep)")
    if tmp is not None:
        tmp.cleanup()


if __name__ == "__main__":
    main()
