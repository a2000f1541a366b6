"""The checks of a case's ``geometry`` that involve several keys (:func:`validate_geometry`,
called first by :func:`fsi.config.validation.validate`): finite lengths, the dimension, the
stenosis' plaque (its sides, length, centre, cap and lipid pool, and in 3D its angle) and the
Turek–Hron flag. Each raises :class:`~fsi.config.reader.ConfigError` naming the key.
"""

from __future__ import annotations

import dataclasses
import functools
import math

from fsi.config.case import Case
from fsi.config.domain import (
    StenosisGeometry,
    TubeGeometry,
    TurekHronGeometry,
    dimension,
)
from fsi.config.fluid_section import FLOW_RATE_INLETS, ParabolicInflow
from fsi.config.reader import ConfigError
from fsi.geometry import stenosis as stenosis_geometry
from fsi.geometry import vessel_3d

MAX_LENGTH = 1.0e100
"""The largest length (m) a geometry may give: the geometry's arithmetic squares lengths, and
``geometry.height: 1.7e308`` overflowed into a traceback (exit 1) instead of a refusal."""


def validate_geometry(case: Case) -> None:
    g = case.geometry
    for f in dataclasses.fields(g):
        value = getattr(g, f.name)
        if f.metadata.get("unit") == "m" and isinstance(value, float) and value > MAX_LENGTH:
            raise ConfigError(
                "", f"geometry.{f.name}", f"a length of at most {MAX_LENGTH:g} m", value
            )
    _validate_dimension(g)
    _validate_sector(case)
    if isinstance(g, StenosisGeometry):
        _validate_stenosis(g)
    elif isinstance(g, TurekHronGeometry):
        # Any structure mode: 'rigid' is the CFD benchmark, the others make the flag elastic.
        _validate_turek_hron(g)
    elif isinstance(g, TubeGeometry):
        # 'rigid' is a rigid pipe; the wall is the whole structure, so nothing would move
        # with 'fixed_wall' (which holds the vessel wall and lets the plaque move).
        if case.structure.mode == "fixed_wall":
            raise ConfigError(
                "",
                "structure.mode",
                "'rigid' or 'moving_wall' for geometry.kind 'tube' (it has no plaque:"
                " 'fixed_wall' would hold all of its structure)",
                case.structure.mode,
            )
    elif case.structure.mode != "rigid":
        raise ConfigError(
            "",
            "structure.mode",
            f"'rigid' for geometry.kind '{g.kind}' (it has no structure)",
            case.structure.mode,
        )


def _validate_dimension(g) -> None:
    """A 3D vessel is meshed whole (not as the axisymmetric meridian plane) and its plaque
    spans ``plaque_angle``, which a plane or axisymmetric plaque cannot."""
    if dimension(g) == 3 and g.axisymmetric:
        raise ConfigError(
            "",
            "geometry.axisymmetric",
            "false with geometry.dimension 3 (the 3D vessel is the solid itself;"
            " axisymmetric is its 2D meridian-plane model)",
            g.axisymmetric,
        )
    if isinstance(g, StenosisGeometry) and dimension(g) == 2 and g.plaque_angle != 360:
        raise ConfigError(
            "",
            "geometry.plaque_angle",
            "360 unless geometry.dimension is 3 (a plane or axisymmetric plaque spans no angle)",
            g.plaque_angle,
        )


def _validate_sector(case: Case) -> None:
    """A quarter (``sector: 90``) is a 3D tube's or a concentric 3D stenosis's (its cuts are
    mirror planes of the solution only then), and its inlet a pressure inlet: a velocity
    inlet's profile is laid out on a whole disk (fsi/physics/fluid_boundaries.py)."""
    g = case.geometry
    if getattr(g, "sector", 360) == 360:
        return
    if dimension(g) != 3:
        raise ConfigError("", "geometry.sector", "360 unless geometry.dimension is 3", g.sector)
    if getattr(g, "plaque_angle", 360) != 360:
        raise ConfigError(
            "",
            "geometry.sector",
            f"360 with geometry.plaque_angle {g.plaque_angle} (a quarter models a concentric "
            "plaque only, plaque_angle 360)",
            g.sector,
        )
    if isinstance(case.fluid.inlet, (ParabolicInflow, *FLOW_RATE_INLETS)):
        raise ConfigError(
            "",
            "fluid.inlet.kind",
            "a pressure inlet with geometry.sector 90 (a velocity inlet's profile needs the "
            "whole disk)",
            case.fluid.inlet.kind,
        )


def _validate_stenosis(g: StenosisGeometry) -> None:
    """Plaque sides once each; the stenosis (its length and its centre) inside the segment;
    the cap thinner than the plaque and nowhere thinner than ``cap_thickness`` over the lipid
    pool."""
    _validate_plaque_sides(g)
    _refuse_not_shorter(g, "stenosis_length", than="length")
    half = g.stenosis_length / 2
    if not half < stenosis_geometry.apex_x(g) < g.length - half:
        raise ConfigError(
            "",
            "geometry.stenosis_centre",
            f"a plaque inside the segment: between stenosis_length / 2 = {half:g} m and length"
            f" - stenosis_length / 2 = {g.length - half:g} m",
            g.stenosis_centre,
        )
    plaque = stenosis_geometry.plaque_height(g)
    if g.cap_thickness >= plaque:
        raise ConfigError(
            "",
            "geometry.cap_thickness",
            f"less than the plaque height {plaque:g} m (stenosis_degree × height / plaque sides)",
            g.cap_thickness,
        )
    _refuse_not_shorter(g, "lipid_length", than="stenosis_length")
    _validate_plaque_angle(g, plaque)
    thinnest = _thinnest_cap(g)
    if thinnest < g.cap_thickness * (1 - 1e-4):
        raise ConfigError(
            "",
            "geometry.lipid_length",
            "a lipid pool short enough that the fibrous cap is nowhere thinner"
            f" than cap_thickness = {g.cap_thickness} m (it would be"
            f" {thinnest:.3g} m)",
            g.lipid_length,
        )


def _validate_plaque_sides(g: StenosisGeometry) -> None:
    """``plaque_sides``: not with an axisymmetric or a 3D vessel; else once each."""
    if g.axisymmetric and g.plaque_sides is not None:
        raise ConfigError(
            "",
            "geometry.plaque_sides",
            "no plaque_sides with geometry.axisymmetric (the plaque is a concentric ring on the"
            " vessel's wall; the bottom side is the axis)",
            list(g.plaque_sides),
        )
    if dimension(g) == 3 and g.plaque_sides is not None:
        raise ConfigError(
            "",
            "geometry.plaque_sides",
            "no plaque_sides with geometry.dimension 3 (the plaque spans geometry.plaque_angle"
            " about +y)",
            list(g.plaque_sides),
        )
    sides = stenosis_geometry.sides(g)
    if len(set(sides)) != len(sides) or not sides:
        raise ConfigError(
            "", "geometry.plaque_sides", "'bottom', 'top' or both, once each", list(sides)
        )


def _validate_plaque_angle(g: StenosisGeometry, plaque: float) -> None:
    """In 3D, ``plaque_angle``: 360 or at most 359 degrees, and wide enough for the cap to cover
    the lipid pool's two ends (``plaque`` the plaque's height, m)."""
    if dimension(g) == 3 and 359 < g.plaque_angle < 360:
        raise ConfigError(
            "",
            "geometry.plaque_angle",
            "360 (concentric) or at most 359 degrees: a narrower strip of healthy wall cannot be"
            " meshed (359.9 failed in gmsh)",
            g.plaque_angle,
        )
    if dimension(g) == 3 and vessel_3d.lipid_angle(g) <= 0:
        inner = g.height - (plaque - g.cap_thickness)
        least = 2 * math.degrees(math.asin(min(1.0, g.cap_thickness / inner)))
        raise ConfigError(
            "",
            "geometry.plaque_angle",
            f"more than {least:.4g} degrees, the angle of the cap that covers the lipid pool's"
            f" two ends by cap_thickness = {g.cap_thickness} m",
            g.plaque_angle,
        )


@functools.lru_cache(maxsize=1024)
def _thinnest_cap(g: StenosisGeometry) -> float:
    """The fibrous cap's thinnest point (m), once per geometry: a sweep validates many cases
    that share theirs."""
    return stenosis_geometry.min_cap_thickness(g)


def _refuse_not_shorter(g: StenosisGeometry, key: str, than: str) -> None:
    """Refuse ``geometry.<key>`` unless it is less than ``geometry.<than>`` (lengths, m)."""
    length, limit = getattr(g, key), getattr(g, than)
    if length >= limit:
        raise ConfigError("", f"geometry.{key}", f"less than geometry.{than} = {limit} m", length)


def _validate_turek_hron(g: TurekHronGeometry) -> None:
    """The cylinder inside the channel, the flag attached to it and ending inside the channel."""
    if len(g.cylinder_centre) != 2:
        raise ConfigError(
            "",
            "geometry.cylinder_centre",
            "a list of two numbers [x, y] (m)",
            list(g.cylinder_centre),
        )
    cx, cy = g.cylinder_centre
    r = g.cylinder_radius
    if not (r < cx and r < cy < g.height - r):
        raise ConfigError(
            "",
            "geometry.cylinder_radius",
            f"a cylinder of centre {list(g.cylinder_centre)} inside the channel"
            f" [0, {g.length}] x [0, {g.height}] m",
            r,
        )
    if g.flag_thickness >= 2 * r:
        raise ConfigError(
            "",
            "geometry.flag_thickness",
            f"less than the cylinder diameter {2 * r} m",
            g.flag_thickness,
        )
    if cx + r + g.flag_length >= g.length:
        raise ConfigError(
            "",
            "geometry.flag_length",
            f"a flag tip (x = centre + radius + length) before the outlet x = {g.length} m",
            g.flag_length,
        )
