"""ProxQP loaded in its build without AVX, so that a solve gives the same numbers to the last bit in every process.

``import proxsuite`` loads the build for the widest vector instructions the processor has (AVX-512, else AVX2). Those
builds' sums run over 32- or 64-byte packets, but part of ProxQP's working memory is only 16-byte aligned by the
system allocator: where a buffer lands decides how many leading entries are summed one by one before the packets
start, so a fresh QP object answers one of two results 1e-21 apart (the same object re-solving gives its own one
again). A warm-started run carries that last bit on, and held contacts on box-push gave drift_growth_exponent
0.7789562733022365 in one process and 0.7789559511382355 in the next. The baseline build (SSE2, 16-byte packets,
which every allocation meets) gives one answer whatever the addresses, and the same one on every x86-64 processor;
its solves are the same size (tens of variables), where the wider packets gain little.

The build is chosen when proxsuite is first imported, and one build only can live in a process: every pinstab module
takes proxsuite from here. When proxsuite was imported before pinstab, the build already loaded is kept, with a
:class:`~pinstab.errors.PinstabWarning` that its last bits may then differ between processes.
"""

from __future__ import annotations

import sys
import types
import warnings

from .errors import PinstabWarning

BASELINE = "proxsuite.proxsuite_pywrap"  # the build without AVX

if "proxsuite" not in sys.modules:
    # proxsuite/__init__.py asks its `instructionset` module which build to load: answer "no AVX" for this import
    _no_avx = types.ModuleType("proxsuite.instructionset")
    _no_avx.has_AVX512F = _no_avx.has_AVX2 = lambda: False
    sys.modules["proxsuite.instructionset"] = _no_avx
    try:
        import proxsuite
    finally:
        del sys.modules["proxsuite.instructionset"]
else:
    import proxsuite

BUILDS = ("proxsuite.proxsuite_pywrap_avx512", "proxsuite.proxsuite_pywrap_avx2", BASELINE)


def loaded_build() -> str:
    """The module name of the proxsuite build this process loaded (one of :data:`BUILDS`; proxsuite 0.6 and 0.8
    both import it as a submodule)."""
    return next((name for name in BUILDS if name in sys.modules), BASELINE)


if loaded_build() != BASELINE:
    warnings.warn(
        f"proxsuite was imported before pinstab and loaded {loaded_build()}: its solves may differ "
        "in the last bits between processes (import pinstab first for the same numbers in every run)",
        PinstabWarning,
        stacklevel=2,
    )

__all__ = ["BASELINE", "BUILDS", "loaded_build", "proxsuite"]
