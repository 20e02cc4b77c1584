"""_shares.py — the split of views among workers (ivr.mpi's ranks), over the C API's
ivr_view_shares, and the C arrays of weights the shared calls take."""
import ctypes

from . import _check, _library


def _doubles(values):
    """A C array of doubles for the C API (None: NULL)."""
    return None if values is None else (ctypes.c_double * len(values))(*map(float, values))


def view_shares_by(n, weights, each=True):
    """[(first, count)] for every weight, in order: n views (or rays) cut into contiguous shares in
    proportion to `weights` (the C API's ivr_view_shares; empty ones kept). each=True: every
    share at least one view where n >= len(weights) (as `mpirun ivr` gives the ranks)."""
    counts = (ctypes.c_size_t * len(weights))()
    _check(_library().ivr_view_shares(int(n), _doubles(weights), len(weights), 1 if each else 0,
                                      counts))
    out, first = [], 0
    for c in counts:
        out.append((first, c))
        first += c
    return out
