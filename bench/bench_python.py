#!/usr/bin/env python3
"""Python-module benchmarks (BENCHMARKS.md "Python module").

    bench_python.py convert [--vertices N]      numpy -> Mesh / NoisyMesh (V, F with 2N faces, covariances),
                                                beside numpy's own copy of the same arrays
    bench_python.py smooth MESH OUT [--noise K]  what `rangebayes smooth MESH OUT --noise K` does, from Python:
                                                 prints the CPU time of the smooth() call and of the process
Run with PYTHONPATH=build/<preset>/python /usr/bin/python3.
"""

import argparse
import resource
import sys
import time

import numpy as np

import rangebayes as rb


def cpu_s():
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def best_of(repeat, make):
    """(best wall s, best CPU s) of make() over repeat runs; CPU is the whole process's (all threads)."""
    best = best_cpu = float("inf")
    for _ in range(repeat):
        m = None  # the last result is freed before the clock starts
        c0, t0 = time.process_time(), time.perf_counter()
        m = make()
        best = min(best, time.perf_counter() - t0)
        best_cpu = min(best_cpu, time.process_time() - c0)
    del m
    return best, best_cpu


def convert(args):
    n = args.vertices
    rng = np.random.default_rng(1)
    V = rng.normal(size=(n, 3))
    F = rng.integers(0, n, size=(2 * n, 3), dtype=np.int32)
    cov = np.broadcast_to(np.eye(3) * 1e-4, (n, 3, 3)).copy()
    F64 = F.astype(np.int64)  # numpy's default integer
    covF = np.asfortranarray(cov)
    mb = (V.nbytes + F.nbytes + cov.nbytes) / 1e6
    print(f"{n} vertices, {2 * n} faces ({mb:.0f} MB with covariances), best of {args.repeat}; "
          f"CPU = process CPU (all threads)")
    rows = [
        ("numpy V.copy(), F.copy(), cov.copy()", lambda: (V.copy(), F.copy(), cov.copy())),
        ("Mesh(V, F)", lambda: rb.Mesh(V, F)),
        ("NoisyMesh(V, F, covariances)", lambda: rb.NoisyMesh(V, F, cov)),
        ("NoisyMesh(V, F, cov) int64 F", lambda: rb.NoisyMesh(V, F64, cov)),
        ("NoisyMesh(V, F, cov) Fortran cov", lambda: rb.NoisyMesh(V, F, covF)),
    ]
    target = rb.NoisyMesh(V, F, cov)

    def assign():
        target.V, target.F, target.covariances = V, F, cov  # same shapes: into the existing storage

    np_V, np_F, np_cov = np.empty_like(V), np.empty_like(F), np.empty_like(cov)
    rows += [
        ("numpy copyto() into existing arrays", lambda: (np.copyto(np_V, V), np.copyto(np_F, F), np.copyto(np_cov, cov))),
        ("assign V, F, covariances (same size)", assign),
    ]
    for label, make in rows:
        wall, cpu = best_of(args.repeat, make)
        print(f"{label:38s} wall {wall * 1e3:6.1f} ms, CPU {cpu * 1e3:6.1f} ms")
    m = rb.NoisyMesh(V, F, cov)
    t0 = time.perf_counter()
    views = (m.V, m.F, m.covariances)
    print(f"{'views V, F, covariances':38s} {(time.perf_counter() - t0) * 1e6:.0f} us (no copy)")
    assert views[0].base is not None


def smooth(args):
    c0 = cpu_s()
    w0 = time.perf_counter()
    mesh = rb.read_mesh(args.mesh)
    c1 = cpu_s()
    out, summary = rb.smooth(mesh, noise=args.noise)
    c2 = cpu_s()
    rb.write_mesh(args.out, out)
    print(summary.brief_report(), end="")
    print(f"smooth() CPU {c2 - c1:.2f} s, summary.time_s {summary.time_s:.2f} s (wall); "
          f"read+smooth+write wall {time.perf_counter() - w0:.2f} s, CPU {cpu_s() - c0:.2f} s")


def main():
    p = argparse.ArgumentParser()
    sub = p.add_subparsers(dest="cmd", required=True)
    c = sub.add_parser("convert")
    c.add_argument("--vertices", type=int, default=1_000_000)
    c.add_argument("--repeat", type=int, default=10)
    s = sub.add_parser("smooth")
    s.add_argument("mesh")
    s.add_argument("out")
    s.add_argument("--noise", type=float, default=None)
    args = p.parse_args()
    {"convert": convert, "smooth": smooth}[args.cmd](args)


if __name__ == "__main__":
    sys.exit(main())
