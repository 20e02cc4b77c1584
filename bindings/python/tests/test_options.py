"""The option structs of the binding against the C header: the same fields in the same order and
C types, filled by the library's init functions (so the binding holds no defaults of its own)."""
import ctypes
import pathlib
import re

import pytest

import ivr
from ivr import _capi

HEADERS = pathlib.Path(__file__).resolve().parents[3] / "include" / "ivr"
C_TYPES = {"int": ctypes.c_int, "double": ctypes.c_double, "size_t": ctypes.c_size_t,
           "uint64_t": ctypes.c_uint64}


def header_fields(header, name):
    text = (HEADERS / header).read_text()
    body = text[text.index("typedef struct %s {" % name):text.index("} %s;" % name)]
    body = re.sub(r"/\*.*?\*/", "", body, flags=re.S)
    fields = re.findall(r"\n\s*([A-Za-z_]\w*)\s+([A-Za-z_]\w*)\s*;", body)
    return [(field, C_TYPES.get(ctype, ctypes.c_int)) for ctype, field in fields]


@pytest.mark.parametrize("header,name,struct,init", [
    ("ivr.h", "ivr_tomo_options", _capi.TomoOptions, "ivr_tomo_options_init"),
    ("ivr.h", "ivr_reconstruct_options", _capi.ReconstructOptions, "ivr_reconstruct_options_init"),
    ("ivr.h", "ivr_viewpoint_options", _capi.ViewpointOptions, "ivr_viewpoint_options_init"),
    ("ivr_session.h", "ivr_session_options", _capi.SessionOptions, "ivr_session_options_init"),
])
def test_option_structs_match_the_header_and_take_the_library_defaults(header, name, struct, init):
    assert list(struct._fields_) == header_fields(header, name)
    lib = ivr._library()
    options = _capi.filled(struct, getattr(lib, init), ivr._check)
    assert options.size == ctypes.sizeof(struct)  # the library's sizeof: the layouts agree


def test_values_given_replace_the_defaults_and_none_keeps_them():
    lib = ivr._library()
    default = _capi.filled(_capi.TomoOptions, lib.ivr_tomo_options_init, ivr._check)
    o = _capi.filled(_capi.TomoOptions, lib.ivr_tomo_options_init, ivr._check, iterations=7,
                     tv=0.5, tikhonov=None)
    assert (o.iterations, o.tv) == (7, 0.5)
    assert o.tikhonov == default.tikhonov and o.tv_epsilon == default.tv_epsilon
