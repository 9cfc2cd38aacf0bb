"""Limit BLAS threads before numpy is imported.

The fit's matrices are small: on 2 cores one BLAS thread is fastest and steadiest, and a
busy multi-threaded BLAS makes tiny solves many times slower. This module imports nothing
heavy, so a benchmark can call it before numpy loads.
"""

import argparse
import os

VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def limit(threads):
    """Set the BLAS thread variables to ``threads`` (a string) unless the environment
    already sets them; ``"default"`` leaves the library's choice."""
    if threads != "default":
        for var in VARIABLES:
            os.environ.setdefault(var, threads)


def script_args(parse, name):
    """The benchmark's parsed command line when it runs as a script (``name`` is
    ``"__main__"``), with its ``--blas-threads`` applied before numpy loads; else None
    (imported, e.g. for a helper function)."""
    if name != "__main__":
        return None
    args = parse()
    limit(args.blas_threads)
    return args


def parser(prog, description):
    """An argument parser for a benchmark script, with ``--blas-threads`` (default one
    thread unless the environment says otherwise)."""
    p = argparse.ArgumentParser(prog=prog, description=description,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--blas-threads", default="1",
                   help="BLAS threads (OPENBLAS/OMP/MKL_NUM_THREADS) unless already set in "
                        "the environment; the fit's matrices are small, so one thread is "
                        "fastest and steadiest ('default' leaves the library's choice)")
    return p


def option_argument(p):
    """Add ``--set NAME=VALUE`` (repeatable) to a benchmark's parser: any FitOptions field
    of every fit it runs (``common.option_values`` reads them)."""
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                   help="a FitOptions field of every fit (a JSON value, else a string), "
                        "e.g. --set lambda2=1.5; repeatable")
