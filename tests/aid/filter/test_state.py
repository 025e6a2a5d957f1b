"""The state layout (imugen.aid.filter.state): one list of blocks gives every offset; the
names, offsets, the kernel's view and the feedback table agree for every combination of
switches; the options switch the blocks they document."""

import itertools

import numpy as np
import pytest

from imugen.aid import filter as A
from imugen.aid.filter.state import BLOCKS, Offsets, StateLayout, state_names

SWITCHES = ("scale_factors", "gnss_bias", "odo_sf", "baro", "mounting", "gyro_cc", "odometer",
            "lever")  # fmt: skip


@pytest.mark.parametrize("on", list(itertools.product((False, True), repeat=len(SWITCHES))))
def test_names_offsets_and_kernel_view_agree(on):
    lay = StateLayout.of(**dict(zip(SWITCHES, on, strict=True)))
    names = state_names(*on)
    assert names == lay.names and len(names) == lay.n
    off = lay.offsets()
    covered = np.zeros(lay.n, int)
    for b in BLOCKS:
        if not lay.has(b.key):
            assert getattr(off, b.key) == -1
            continue
        i = lay.offset(b.key)
        assert getattr(off, b.key) == i
        assert names[lay.slice(b.key)] == list(b.names)
        covered[lay.slice(b.key)] += 1
    assert np.all(covered == 1) and off.n == lay.n  # contiguous, no overlap
    for xi, ei, cnt in lay.feedback_table():  # nominal and error offsets of one block
        key = next(b.key for b in lay.blocks if lay.offset(b.key) == ei)
        assert A.NOMINAL.offset(key) == xi and cnt == min(A.NOMINAL.size(key), lay.size(key))
        assert key != "att"


def test_the_nominal_state_holds_every_block():
    assert A.NOMINAL.n == A.NX == sum(b.nominal for b in BLOCKS)
    assert A.NOMINAL.slice("att") == slice(6, 10)  # the quaternion
    assert tuple(A.NOMINAL.offsets())[:-1] == tuple(
        int(np.sum([b.nominal for b in BLOCKS[:i]])) for i in range(len(BLOCKS))
    )
    assert Offsets._fields[:-1] == tuple(b.key for b in BLOCKS)


def test_the_options_switch_their_blocks():
    full = A.Options(
        scale_factors=True, nhc=True, odometer=True, baro=True,
        nhc_misalignment_sd_rad=(0.01, 0.01), nhc_lever_arm_sd_m=(0.1, 0.1, 0.1),
    )  # fmt: skip
    assert {b.key for b in full.layout.blocks} == {b.key for b in BLOCKS}
    assert full.n == A.NX - 1 + 1  # nominal quaternion 4 -> psi 3; tick residuals 1 -> 2
    assert full.names() == full.layout.names
    # the mounting and lever-arm states only with NHC, the tick states with the odometer
    no_nhc = A.Options(
        nhc=False, nhc_misalignment_sd_rad=(0.01, 0.01), nhc_lever_arm_sd_m=(1, 1, 1)
    )
    assert not no_nhc.layout.has("mount") and not no_nhc.layout.has("lever")
    assert not A.Options(odometer=True, odo_scale_state=False).layout.has("odo_sf")
    assert A.Options(odometer=True).layout.has("odo_tick")
    assert A.Options().names()[:15] == [
        *(f"{g}_{a}" for g in ("dp", "dv", "psi") for a in "enu"),
        *(f"{g}_{a}" for g in ("dbg", "dba") for a in "xyz"),
    ]


def test_a_result_slices_by_block():
    """The result carries its layout: ``sd_of`` gives each block's sigmas."""
    lay = A.Options().layout
    sd = np.arange(2 * lay.n, dtype=float).reshape(1, 2, lay.n)
    res = A.AidedResult(*([None] * 10), sd, None, None, lay.names, layout=lay)
    np.testing.assert_array_equal(res.sd_of("gnss_bias"), sd[..., 15:18])
