"""Pins the BLAS/LAPACK kernels numpy and scipy run on, before either is loaded.

OpenBLAS picks its kernels by CPU at run time (SkylakeX, with AVX-512, on an Intel Xeon;
Haswell on an AMD EPYC), and results differ between them in the last bits. The proving
ground's scenario files came out different on the two machines of sessions 61–67 (seeds
94 and 145: the force column in its last printed digit on most rows), and the knife-edge
decisions on those records with them. Every x86-64 machine with AVX2 and FMA runs the
Haswell kernels, here on one thread, so the files are the same on all of them
(`scenario_sha256.txt` holds their hashes). Import this module before numpy or scipy:
`generate.py` and every script here that loads numpy does.
"""
import os
import sys


def _has_avx2_and_fma():
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("flags"):
                    flags = line.split()
                    return "avx2" in flags and "fma" in flags
    except OSError:
        pass
    return False


if "numpy" in sys.modules and "OPENBLAS_CORETYPE" not in os.environ:
    raise ImportError("pin_blas must be imported before numpy (OpenBLAS reads its kernel "
                      "choice when numpy loads); or set OPENBLAS_CORETYPE=Haswell")
if _has_avx2_and_fma():
    os.environ.setdefault("OPENBLAS_CORETYPE", "Haswell")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
