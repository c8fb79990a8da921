"""Bad arguments from Python raise hpcm.Error naming the argument and what is expected (never
pybind11's "Unable to cast", never a silent default)."""
import math

import numpy as np
import pytest

import hpcm

SMALL = (24, 20, 16)


@pytest.fixture(scope="module")
def sim():
    return hpcm.Simulation(hpcm.phantom(SMALL))


# ---- Volume geometry --------------------------------------------------------------------------

HU = np.full((4, 3, 2), -500.0, dtype=np.float32)


@pytest.mark.parametrize("origin", [(math.nan, 0, 0), (0, math.inf, 0), (0, 0, -math.inf)])
def test_volume_refuses_a_non_finite_origin(origin):
    with pytest.raises(hpcm.Error, match=r"origin\[\d\] = .* must be finite"):
        hpcm.Volume(HU, origin=origin)


@pytest.mark.parametrize("direction, rule", [
    (np.zeros((3, 3)), "unit"),                                           # zero
    ([[1, 0.5, 0], [0, 1, 0], [0, 0, 1]], "unit|orthogonal"),            # sheared
    ([[2, 0, 0], [0, 1, 0], [0, 0, 1]], "unit"),                          # scaled (spacing belongs in spacing)
    ([[1, 0, 0], [0, 1, 0], [0, 1, 0]], "unit|orthogonal"),               # two equal columns
    ([[1, 0, 0], [0, math.nan, 0], [0, 0, 1]], "finite"),
])
def test_volume_refuses_a_direction_that_is_not_orthonormal(direction, rule):
    with pytest.raises(hpcm.Error, match=rf"direction.*({rule})"):
        hpcm.Volume(HU, direction=direction)


def test_volume_accepts_rotations_and_flips():
    c, s = math.cos(0.3), math.sin(0.3)
    v = hpcm.Volume(HU, direction=[[c, -s, 0], [s, c, 0], [0, 0, -1]], origin=(-200.5, 10, 1e4))
    np.testing.assert_allclose(v.direction, [[c, -s, 0], [s, c, 0], [0, 0, -1]])


# ---- the grab tool ------------------------------------------------------------------------------

@pytest.mark.parametrize("centre, expected", [
    ((math.nan, 0, 0), r"grab centre coordinate 0 = nan: .*whole number"),
    ((1.5, 2, 3), r"grab centre coordinate 0 = 1\.5: .*whole number"),
    ((1, 2), r"grab centre \(1, 2\): .*3 whole numbers"),
    ("top", r"grab centre 'top'"),
    (2 ** 70, r"grab centre .*out of range"),
    ([1, "a", 3], r"grab centre coordinate 1 = 'a'"),
    (None, r"grab centre"),
])
def test_grab_centre_errors_name_the_argument(sim, centre, expected):
    with pytest.raises(hpcm.Error, match=expected):
        sim.grab(centre)


def test_grab_centre_accepts_numpy_and_whole_floats(sim):
    sim.grab(np.array([12, 10, 8]))
    assert sim.grab_centre == (12, 10, 8)
    sim.grab((11.0, np.int64(9), np.float32(7)))
    assert sim.grab_centre == (11, 9, 7)
    sim.grab(np.int64(12 + 24 * (10 + 20 * 8)))
    assert sim.grab_centre == (12, 10, 8)
    sim.release()


@pytest.mark.parametrize("radius", [-1.0, math.nan, -math.inf, 64.5, math.inf])
def test_grab_radius_outside_its_range_is_refused(sim, radius):
    # The scenario files' rule: [0, 64] lattice units, 0 meaning solver.grab_radius.
    with pytest.raises(hpcm.Error, match=r"radius .*\[0, 64\]"):
        sim.grab("auto", radius=radius)
    assert not sim.grabbing  # nothing was grabbed with a default radius instead


def test_grab_radius_zero_means_the_default_and_64_is_allowed(sim):
    sim.grab("auto", radius=0)
    default = len(sim.grabbed)
    sim.grab("auto", radius=64)
    assert len(sim.grabbed) > default > 0
    sim.release()


@pytest.mark.parametrize("offset, expected", [
    ("up", r"tool offset 'up': .*3 numbers"),
    ((1, 2), r"tool offset .*3 numbers"),
    ((0, "a", 0), r"tool offset component 1 = 'a'"),
    ((0, math.nan, 0), r"tool offset .*finite"),
    (None, r"tool offset"),
])
def test_move_tool_errors_name_the_argument(sim, offset, expected):
    sim.grab("auto")
    with pytest.raises(hpcm.Error, match=expected):
        sim.move_tool(offset)
    sim.move_tool(np.array([0.0, -0.5, 0.0], dtype=np.float32))  # still usable, numpy accepted
    assert sim.requested_offset == pytest.approx((0.0, -0.5, 0.0))
    sim.release()
