#!/usr/bin/env python3
"""Python-module benchmarks (BENCHMARKS.md "Python module").

    bench_python.py convert [--vertices N]      numpy -> NoisyMesh (V, F with 2N faces, covariances) and back
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


def convert(args):
    n = args.vertices
    rng = np.random.default_rng(1)
    V = rng.normal(size=(n, 3))
    F = rng.integers(0, n, size=(2 * n, 3), dtype=np.int32)
    cov = np.broadcast_to(np.eye(3) * 1e-4, (n, 3, 3)).copy()
    for label, make in [
        ("Mesh(V, F)", lambda: rb.Mesh(V, F)),
        ("NoisyMesh(V, F, covariances)", lambda: rb.NoisyMesh(V, F, cov)),
    ]:
        best = best_cpu = float("inf")
        for _ in range(args.repeat):
            m = None
            c0, t0 = time.process_time(), time.perf_counter()
            m = make()
            best = min(best, time.perf_counter() - t0)
            best_cpu = min(best_cpu, time.process_time() - c0)
        del m
        print(f"{label:32s} {n} vertices, {2 * n} faces: best of {args.repeat}: CPU {best_cpu * 1e3:.1f} ms, "
              f"wall {best * 1e3:.1f} ms")
    m = rb.NoisyMesh(V, F, cov)
    t0 = time.perf_counter()
    views = (m.V, m.F, m.covariances)
    print(f"{'views V, F, covariances':32s} {(time.perf_counter() - t0) * 1e6:.0f} us (no copy)")
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
