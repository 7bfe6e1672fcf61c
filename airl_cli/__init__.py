"""airl: adversarial inverse reinforcement learning with changing dynamics (a command-line experiment runner)."""

import ctypes
import os
import sys

__version__ = "0.1.0"

# The planner's numba kernels enter about sixty short parallel regions a call. Numba's threading
# layer of first choice is Intel TBB, whose idle workers spin briefly and then sleep: on the 2-core
# reference machine the 16x16 zero-one Objectworld fit took 7.7-8.0 s with it against 8.5-8.7 s
# with OpenMP's passive waiting, and 11.8 s against 13-18 s under a load of two busy processes.
# pip installs TBB's library beside the environment's packages, where numba's lookup by name does
# not find it, so it is loaded here, by path, before numba starts a thread (``_load_tbb``).
#
# Without TBB numba takes OpenMP. GNU OpenMP's default lets an idle thread spin for a while between
# parallel regions, and on a machine whose cores are busy with other work the spinning threads crowd
# out the working ones: the 32x32 Objectworld fit took 20.3 s instead of 6.6 s under a load of about
# 3 on 2 cores (the duplicate-removal kernel 13.8 ms a step instead of 0.4 ms). Passive waiting
# costs a wake-up per region (microseconds). Set before numba loads OpenMP; a value the user chose
# is kept.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")


def _same_blas_everywhere() -> None:
    """Pin OpenBLAS's kernels to its Haswell ones on every x86-64 Linux machine that runs them (AVX2
    and FMA), unless the user chose (``OPENBLAS_CORETYPE``); set before numpy and scipy load it.

    OpenBLAS picks its kernels by processor: on an AVX-512 Intel Xeon its SkylakeX kernels, on an
    AMD EPYC its Haswell ones, whose products round differently in the last bit. The certified
    fit's path follows those bits (which adversary strategy enters first at a near-tie), so the
    default fit took 194 iterations on the Xeon and 154 on the EPYC, certifying 9.47161 and 9.47098,
    and a sweep's medians differed in the third decimal. With the kernels pinned the Xeon gives the
    EPYC's bits (measured); numba's kernels and numpy's own vector code gave the same bits on both.
    """
    if not sys.platform.startswith("linux") or "OPENBLAS_CORETYPE" in os.environ:
        return
    try:
        with open("/proc/cpuinfo") as info:
            flags = next((line.split(":", 1)[1].split() for line in info if line.startswith("flags")), [])
    except OSError:
        return
    if "avx2" in flags and "fma" in flags:
        os.environ["OPENBLAS_CORETYPE"] = "Haswell"
        _warn_if_chosen_already()


def _warn_if_chosen_already() -> None:
    """Warn, once, when numpy or scipy loaded OpenBLAS before this import and it chose other kernels
    than Haswell's (an AVX-512 Xeon's SkylakeX): the pin cannot apply any more, and a fit may take
    another path to the same tolerance than the commands take (the default fit: 163 iterations
    certifying 9.47090 instead of 154 and 9.47098 on the Xeon)."""
    if "numpy" not in sys.modules and "scipy" not in sys.modules:
        return
    try:
        from threadpoolctl import threadpool_info

        chosen = {i.get("architecture") for i in threadpool_info() if i.get("internal_api") == "openblas"} - {None, "Haswell"}
    except Exception:  # noqa: BLE001 - a check that cannot run must not stop the import
        return
    if chosen:
        import warnings

        text = (
            f"airl_cli was imported after numpy or scipy, whose OpenBLAS already chose its {', '.join(sorted(chosen))} kernels: "
            "a fit may take another path to the same tolerance than the airl commands take on this machine; "
            "import airl_cli first, or set OPENBLAS_CORETYPE=Haswell before starting Python"
        )
        warnings.warn_explicit(text, RuntimeWarning, "airl_cli", 0, module="airl_cli")  # no line of ours to show


_same_blas_everywhere()


def _load_tbb() -> None:
    """Load the TBB library of the ``tbb`` package (Linux), so that numba's threading layer finds
    it; nothing if the package is absent or the user chose another layer (``NUMBA_THREADING_LAYER``)."""
    if not sys.platform.startswith("linux") or os.environ.get("NUMBA_THREADING_LAYER", "default") not in ("default", "tbb", "safe"):
        return
    from importlib.metadata import PackageNotFoundError, files

    try:
        found = [f for f in files("tbb") or () if f.name == "libtbb.so.12"]
        if found:
            ctypes.CDLL(str(found[0].locate()), mode=ctypes.RTLD_GLOBAL)
    except (PackageNotFoundError, OSError):  # no TBB: numba takes OpenMP
        pass


_load_tbb()


def _numba_cache() -> None:
    """Keep numba's compiled kernels in a folder named for the compiled code's sources (``cache_folder``),
    unless the user chose ``NUMBA_CACHE_DIR``; a folder that cannot be written leaves numba's own choice.

    numba caches a compiled function beside its module and checks only that module's stamp, not
    those of the modules whose functions it compiles in: ``_bound_kernels``' bound kept the grid's
    old interpolation after ``grid_bound`` changed (it had read unfilled scratch on sparse rows:
    the fix ran only with a fresh cache). A change to any module of the core now compiles the
    kernels again, once (about a minute)."""
    if "NUMBA_CACHE_DIR" in os.environ:
        return
    from pathlib import Path

    folder = cache_folder(Path(__file__).parent, os.environ)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        return
    if os.access(folder, os.W_OK):
        os.environ["NUMBA_CACHE_DIR"] = str(folder)


def cache_folder(package, environ):  # noqa: ANN001, ANN201 - kept free of typing imports: it runs at every start
    """``$XDG_CACHE_HOME/airl/numba/<hash of every module of package/core>`` (``~/.cache`` by
    default): the folder numba's cache of this package's kernels goes to (``_numba_cache``)."""
    import hashlib
    from pathlib import Path

    digest = hashlib.sha256()
    for path in sorted((package / "core").rglob("*.py")):
        digest.update(path.relative_to(package).as_posix().encode() + b"\0" + path.read_bytes())
    return Path(environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "airl" / "numba" / digest.hexdigest()[:16]


_numba_cache()
