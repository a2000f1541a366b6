"""fsi/study/locations.py: whether a reported maximum sits at a boundary's corner or an open
boundary's edge, decided from its position and the stenosis's inlet/outlet x and wall y."""

import pytest

from fsi.study import locations

GEOMETRY = {
    "length": 0.02,
    "height": 0.007,
    "wall_thickness": 0.001,
    "stenosis_length": 0.01,
    "stenosis_degree": 0.5,
    "stenosis_centre": None,
    "plaque_sides": ["bottom"],
}


@pytest.mark.parametrize(
    "x,y,expected",
    [
        (0.020, 0.007, "outlet_corner"),  # the P1-P1 coarse run's p(10 ms), issue #47
        (0.020, 0.0, "outlet_corner"),
        (0.0, 0.007, "inlet_corner"),
        (0.0, 0.0035, "inlet"),
        (0.020, 0.003, "outlet"),
        (0.00582, 0.00023, None),  # the plaque's flank
        (0.01, 0.007, None),  # the upper wall, away from the openings
        (0.0199, 0.007, None),  # 0.1 mm upstream of the outlet's corner
    ],
)
def test_a_fluid_point_on_an_open_boundary_or_its_corner(x, y, expected):
    assert locations.boundary_place(x, y, GEOMETRY) == expected


def test_a_point_is_on_a_line_within_the_tolerance_given():
    """Nodes are on the lines to rounding; a cell's centroid is within its own size of them."""
    assert locations.boundary_place(0.02 - 1e-9, 0.007 + 1e-9, GEOMETRY) == "outlet_corner"
    assert locations.boundary_place(8e-5, -3e-5, GEOMETRY, "structure") is None
    assert locations.boundary_place(8e-5, -3e-5, GEOMETRY, "structure", tol=1e-4) == (
        "clamped_corner"
    )


@pytest.mark.parametrize(
    "x,y,expected",
    [
        (0.0, -0.0005, "clamped_end"),
        (0.02, -0.001, "clamped_corner"),  # the exterior's corner
        (0.0, 0.0, "clamped_corner"),  # the lumen side's corner
        (0.01, -0.0005, None),  # mid-wall
        (0.01, 0.003, None),  # the plaque: not clamped
    ],
)
def test_a_structure_point_at_a_clamped_end_or_its_corner(x, y, expected):
    assert locations.boundary_place(x, y, GEOMETRY, "structure") == expected


def test_a_top_plaque_s_wall_layer_is_above_the_lumen():
    top = {**GEOMETRY, "plaque_sides": ["top"]}
    assert locations.boundary_place(0.0, 0.0075, top, "structure") == "clamped_end"
    assert locations.boundary_place(0.0, -0.0005, top, "structure") is None
    assert locations.describe("outlet_corner") == "the outlet's corner with a wall"
    assert locations.describe(None) == ""


def test_an_axisymmetric_vessel_s_wall_is_above_its_lumen():
    """The bottom of an axisymmetric stenosis is the axis; its wall and plaque are on top."""
    axi = {**GEOMETRY, "plaque_sides": None, "axisymmetric": True}
    assert locations.plaque_sides(axi) == ("top",)
    assert locations.boundary_place(0.0, 0.0075, axi, "structure") == "clamped_end"
    assert locations.boundary_place(0.0, -0.0005, axi, "structure") is None
