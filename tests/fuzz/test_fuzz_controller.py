"""Fuzz the STC controller's bytes: hypothesis draws a state and a reading field by field (every
value of every field, and any byte where the C reads a byte: a reading's unused bits) and the
portable C step must do what the Python step does (the same state, action and decision, or the
same refusal); and after any bytes on the line a resync brings the firmware's frame reader back.
The million-pair check is ``stcvision firmware check``; these draws find the corners a uniform
draw rarely hits."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from stcvision.controllers.stc import wire
from stcvision.controllers.stc.fsm import StcPhase

from .fuzzlib import examples

_HOST = {}


def _host():
    if not _HOST:
        from stcvision.controllers.stc.controller import HostC

        _HOST["c"] = HostC()
    return _HOST["c"]


states = st.builds(
    lambda phase, free, where, flags: bytes((phase | free << 4, where, flags)),
    st.integers(0, len(StcPhase) - 1), st.integers(0, 15), st.integers(0, 255), st.integers(0, 255),
)  # fmt: skip
readings = st.builds(
    lambda kind, boxes, neigh, start, landing: bytes((kind, boxes, neigh, start, landing)),
    st.integers(0, 2), st.integers(0, 255), st.integers(0, 255), st.integers(0, wire.NONE), st.integers(0, 255),
)  # fmt: skip


@examples(20)
@given(st.lists(st.tuples(states, readings), min_size=1, max_size=50))
def test_the_c_step_is_the_python_step(pairs):
    from stcvision.controllers.stc.identity import python_out

    s = np.frombuffer(b"".join(p[0] for p in pairs), np.uint8).reshape(-1, wire.STATE_BYTES)
    o = np.frombuffer(b"".join(p[1] for p in pairs), np.uint8).reshape(-1, wire.OBS_BYTES)
    out = _host().step_batch(s, o)
    for (state, reading), got in zip(pairs, out, strict=True):
        want = python_out(state, reading)
        got = got.tobytes()
        if want[0]:  # a refusal: the same code, the state untouched
            assert got[0] == want[0] and got[2:5] == state
        else:
            assert got == want


@pytest.fixture(scope="module")
def host_firmware():
    from stcvision.controllers.stc.mcu import FirmwareController

    fw = FirmwareController("host")
    yield fw
    fw.close()


@examples(1)
@given(noise=st.binary(max_size=200))
def test_after_any_bytes_a_resync_brings_the_firmware_back(host_firmware, noise):
    """Noise on the line (a cut frame, garbage) and then a resync: the firmware answers the next
    request, and its reset state is the initial one (nothing the noise did is kept)."""
    from stcvision.controllers.stc.fsm import initial_state

    fw = host_firmware
    fw.link.port.write(noise)
    fw.link.port.flush()
    fw.link.resync()
    assert fw.link.request("HELLO")[1] == wire.STATE_BYTES
    fw.held = fw.link.request("RESET")
    assert fw.held == wire.encode_state(initial_state())
