"""Millimetres beside lattice units in Python (issue 32, item 2): grab(radius_mm=...),
move_tool(offset_mm=...), FrameReport.grab_offset_mm / requested_offset_mm, and scenarios with
offset_mm / radius_mm. Run by CTest (python_api)."""
import math

import numpy as np
import pytest

import hpcm

THICK = (32, 32, 16)  # the thick-slice phantom: z spacing 6.25 x the in-plane spacing


@pytest.fixture(scope="module")
def thick():
    return hpcm.phantom(THICK, variant="anisotropic")


def coords(sim, index):
    nx, ny, _ = sim.dims
    return np.array([index % nx, (index // nx) % ny, index // (nx * ny)])


def test_grab_radius_mm_holds_the_elements_within_that_many_millimetres(thick):
    sim = hpcm.Simulation(thick, hpcm.Params())
    spacing = np.array(sim.spacing)
    radius_mm = 2.5 * spacing[0]
    sim.grab("auto", radius_mm=radius_mm)
    centre = np.array(sim.grab_centre)
    held = np.array([coords(sim, int(i)) for i in sim.grabbed])
    dist_mm = np.linalg.norm((held - centre) * spacing, axis=1)
    assert dist_mm.max() <= radius_mm + 1e-6
    # An ellipsoid on the lattice: 2 elements each way in x, none above or below (thick slices).
    assert np.abs(held - centre).max(axis=0).tolist() == [2, 2, 0]
    # The same radius in lattice units is a sphere of 2.5 elements: it reaches into other slices.
    lattice = hpcm.Simulation(thick, hpcm.Params())
    lattice.grab("auto", radius=2.5)
    assert len(lattice.grabbed) > len(sim.grabbed)


def test_move_tool_offset_mm_is_divided_by_the_spacing_per_axis(thick):
    sim = hpcm.Simulation(thick, hpcm.Params())
    spacing = np.array(sim.spacing)
    sim.grab("auto")
    mm = (3.0, -20.0, 10.0)
    sim.move_tool(offset_mm=mm)
    assert sim.requested_offset == pytest.approx(tuple(np.array(mm) / spacing), rel=1e-6)
    r = sim.step()
    assert not r.tool_limited
    assert r.requested_offset_mm == pytest.approx(math.hypot(*mm), rel=1e-5)
    assert r.grab_offset_mm == pytest.approx(math.hypot(*mm), rel=1e-5)
    assert r.grab_offset == pytest.approx(float(np.linalg.norm(np.array(mm) / spacing)), rel=1e-5)
    assert r.to_dict()["grab_offset_mm"] == r.grab_offset_mm
    # Lattice units as before, positional or by name.
    sim.move_tool((0.0, -1.0, 0.0))
    assert sim.requested_offset == (0.0, -1.0, 0.0)
    sim.move_tool(offset=(0.0, -2.0, 0.0))
    assert sim.requested_offset == (0.0, -2.0, 0.0)
    cols = sim.run(2)
    assert cols["requested_offset_mm"] == pytest.approx([2 * spacing[1]] * 2, rel=1e-5)


def test_exactly_one_unit_and_radius_mm_range(thick):
    sim = hpcm.Simulation(thick, hpcm.Params())
    with pytest.raises(ValueError, match="radius .lattice units. or radius_mm .millimetres., not both"):
        sim.grab("auto", radius=2, radius_mm=5)
    for bad in (-1.0, 0.0, float("nan"), float("inf")):
        with pytest.raises(hpcm.Error, match="radius_mm = .* must be > 0 mm and at most 64 lattice units along every axis"):
            sim.grab("auto", radius_mm=bad)
    assert not sim.grabbing
    sim.grab("auto")
    with pytest.raises(ValueError, match="offset .lattice units. or offset_mm .millimetres., exactly one"):
        sim.move_tool((0.0, 1.0, 0.0), offset_mm=(0.0, 5.0, 0.0))
    with pytest.raises(ValueError, match="exactly one"):
        sim.move_tool()


def test_a_scenario_in_millimetres_pulls_the_same_distance_at_every_downsample():
    text = """
[scenario]
frames = 12
[[grab]]
radius_mm = 20
release = 12
keyframes = [{ frame = 10, offset_mm = [0.0, -25.0, 0.0] }]
"""
    sc = hpcm.Scenario.from_toml(text)
    pulled = []
    for dims in ((48, 48, 16), (24, 24, 8)):  # the same field of view, half the elements
        sim = hpcm.Simulation(hpcm.phantom(dims, variant="anisotropic"), hpcm.Params())
        player = hpcm.ScenarioPlayer(sc, sim)
        while not player.done:
            r = player.step()
        assert not r.tool_limited
        pulled.append(r.grab_offset_mm)
    assert pulled == pytest.approx([25.0, 25.0], rel=1e-5)
