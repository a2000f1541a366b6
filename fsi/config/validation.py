"""The checks of a case that involve several keys (:func:`validate`); each single value is
checked while it is built (:mod:`fsi.config.reader`). Every failure is a :class:`ConfigError`
naming the key; :func:`fsi.config.from_dict` adds the file (or ``--set``).
"""

from __future__ import annotations

import math

from fsi.config.boundary_data import FormulaError, periodic, sample_times, time_function
from fsi.config.case import Case, heartbeat_period, run_time
from fsi.config.domain import (
    TurekHronGeometry,
    dimension,
    is_axisymmetric,
)
from fsi.config.fluid_section import (
    FLOW_RATE_INLETS,
    TABLE_INLETS,
    WAVEFORM_FILES,
    InletFlowRate,
    InletPressure,
    ParabolicInflow,
)
from fsi.config.geometry_validation import validate_geometry
from fsi.config.petsc_options import check_petsc_options
from fsi.config.reader import ConfigError
from fsi.config.rheology_section import womersley_viscosity
from fsi.config.run_size import BYTES_PER_CELL, count_steps, estimated_cells, format_count
from fsi.config.time_section import Time
from fsi.numerics.timestepping import SAME_TIME, steps


def validate(case: Case) -> None:
    """Checks that involve several keys (single values are checked while building), in the
    order of the sections: geometry, structure load, mesh size, schedule, solvers, fluid element,
    inlet."""
    validate_geometry(case)
    _validate_structure_load(case)
    _validate_materials(case)
    _validate_prestress(case)
    _validate_cell_count(case)  # before the size order: mesh.size 1e-6 gets the estimate
    if case.mesh.local_size > case.mesh.size:
        raise ConfigError(
            "", "mesh.local_size", f"at most mesh.size = {case.mesh.size} m", case.mesh.local_size
        )
    _validate_lumen_size(case)
    _validate_schedule(case)
    _validate_solvers(case)
    _validate_element(case)
    check_petsc_options(case.fluid.solver.petsc_options, "fluid.solver.petsc_options")
    check_petsc_options(case.structure.solver.petsc_options, "structure.solver.petsc_options")
    check_petsc_options(case.mesh_motion.petsc_options, "mesh_motion.petsc_options")
    _validate_inlet(case)  # last: it walks the schedule, now known to be of bounded length


def _validate_lumen_size(case: Case) -> None:
    """``mesh.lumen_size``: at most ``mesh.size``, and only where there is a 3D stenosis' lumen."""
    lumen = case.mesh.lumen_size
    if lumen is None:
        return
    g = case.geometry
    if g.kind != "stenosis" or getattr(g, "dimension", 2) != 3:
        raise ConfigError(
            "", "mesh.lumen_size", "null except for a 3D stenosis (geometry.dimension: 3)", lumen
        )
    if lumen > case.mesh.size:
        raise ConfigError("", "mesh.lumen_size", f"at most mesh.size = {case.mesh.size} m", lumen)


def cannot_run(case: Case) -> str | None:
    """Why ``fsi run``, ``fsi check`` (and each run of ``fsi sweep``) refuse this case, checked
    before any computation, or None: a coupled structure of another degree than the fluid's P2
    velocity."""
    mode = case.structure.mode
    if mode != "rigid" and case.structure.interface_load == "fluid":
        if case.structure.degree != 2:
            return (
                f"structure.degree: the coupling pairs the fluid's P2 velocity nodes with "
                f"the structure's interface nodes, so structure.mode '{mode}' needs "
                f"structure.degree 2, got {case.structure.degree}"
            )
    return None


def _validate_materials(case: Case) -> None:
    """``hgo`` needs its ``fibres`` (and no other law takes them), a 3×3 deformation
    (axisymmetric: the fibres lie in the circumferential–axial plane, which a plane section does
    not contain) and a region that is part of the geometry's structure."""
    s = case.structure
    for region in ("wall", "cap", "lipid", "flag"):
        material = getattr(s, region)
        key = f"structure.{region}"
        if material.law == "hgo" and material.fibres is None:
            raise ConfigError(
                "", f"{key}.fibres", "the fibres of law 'hgo' (k1, k2, angle, dispersion)", None
            )
        if material.law != "hgo" and material.fibres is not None:
            raise ConfigError(
                "",
                f"{key}.law",
                "'hgo' when fibres are given (only the HGO law has fibres)",
                material.law,
            )
        if material.law != "hgo" or s.mode == "rigid":
            continue
        if region == "flag" or not (
            is_axisymmetric(case.geometry) or dimension(case.geometry) == 3
        ):
            raise ConfigError(
                "",
                f"{key}.law",
                "'svk' or 'neo_hookean' in a plane model: the HGO fibres lie in the "
                "circumferential-axial plane, which only an axisymmetric (geometry.axisymmetric"
                ": true) or a 3D (geometry.dimension: 3) vessel has",
                material.law,
            )


def _validate_prestress(case: Case) -> None:
    """A prestress needs a structure, drawn as a vessel under pressure (not the Turek–Hron flag)."""
    s = case.structure
    if s.prestress is None:
        return
    if s.mode == "rigid":
        raise ConfigError(
            "",
            "structure.prestress",
            "null when structure.mode is 'rigid' (there is no structure to prestress)",
            "a prestress",
        )
    if isinstance(case.geometry, TurekHronGeometry):
        raise ConfigError(
            "",
            "structure.prestress",
            "null for geometry.kind 'turek_hron' (the flag is not drawn under a pressure)",
            "a prestress",
        )


def _validate_structure_load(case: Case) -> None:
    if case.structure.interface_load != "fluid":
        if case.structure.mode == "rigid":
            raise ConfigError(
                "",
                "structure.interface_load",
                "'fluid' when structure.mode is 'rigid' (there is no structure to load)",
                case.structure.interface_load,
            )
        if case.structure.interface_load == "inlet_pressure" and isinstance(
            case.fluid.inlet, (ParabolicInflow, *FLOW_RATE_INLETS)
        ):
            raise ConfigError(
                "",
                "structure.interface_load",
                "'fluid' or 'none' with a velocity inlet ('inlet_pressure' needs a traction inlet)",
                case.structure.interface_load,
            )


def _validate_cell_count(case: Case) -> None:
    """Refuse a mesh whose :func:`fsi.config.run_size.estimated_cells` exceeds
    ``mesh.max_cells``, before gmsh."""
    cells = estimated_cells(case)
    if cells > case.mesh.max_cells:
        m = case.mesh
        gigabytes = cells * BYTES_PER_CELL / 1e9
        memory = (
            f"{gigabytes:.2g} GB"
            if gigabytes < 10
            else f"{gigabytes:,.0f} GB"
            if gigabytes < 1e9
            else "too much"
        )
        if dimension(case.geometry) == 3:  # no 3D run has measured its memory yet
            kind, need = "tetrahedra", ""
        else:
            kind = "triangles"
            need = f" (a coupled run needs ~{BYTES_PER_CELL / 1e3:.0f} kB per triangle: {memory})"
        raise ConfigError(
            "",
            "mesh",
            reason=(
                f"{format_count(cells)} {kind} estimated (mesh.size = {m.size:g} m, "
                f"mesh.local_size = {m.local_size:g} m, mesh.level = {m.level}), more than "
                f"mesh.max_cells = {m.max_cells:,}{need}: use larger sizes or a "
                "coarser level, or raise mesh.max_cells if you "
                "mean it"
            ),
        )


def _validate_schedule(case: Case) -> None:
    """Segments in increasing order covering the run (one heartbeat's with ``time.cycles``),
    and at most ``time.max_steps`` steps."""
    schedule = case.time.schedule
    if not schedule:
        raise ConfigError("", "time.schedule", "at least one {until, dt} segment", [])
    for i in range(1, len(schedule)):
        if schedule[i].until <= schedule[i - 1].until:
            raise ConfigError(
                "",
                f"time.schedule[{i}].until",
                f"greater than time.schedule[{i - 1}].until = {schedule[i - 1].until} s",
                schedule[i].until,
            )
    _validate_step_control(case.time)
    period = heartbeat_period(case)
    _validate_steps_per_period(case, period)
    _validate_cycles(case.time, period)
    if case.time.cycles >= 1 and period > 0:  # the schedule is one heartbeat's
        if schedule[-1].until < period * (1 - 1e-12):
            raise ConfigError(
                "",
                f"time.schedule[{len(schedule) - 1}].until",
                f"at least fluid.inlet.period = {period} s (with time.cycles the "
                "schedule is one heartbeat's)",
                schedule[-1].until,
            )
    elif schedule[-1].until < case.time.end * (1 - 1e-12):
        raise ConfigError(
            "",
            f"time.schedule[{len(schedule) - 1}].until",
            f"at least time.end = {case.time.end} s",
            schedule[-1].until,
        )
    run = run_time(case)
    count = count_steps(run)
    if count > case.time.max_steps:
        raise_limit = (
            f"raise the limit (--set time.max_steps={int(count)}) if you mean it"
            if math.isfinite(count)
            else "no limit can be that high"
        )
        to = (
            f"time.end = {case.time.end:g} s"
            if run is case.time
            else f"the end of time.cycles = {case.time.cycles} heartbeats, {run.end:g} s"
        )
        raise ConfigError(
            "",
            "time.schedule",
            reason=(
                f"{format_count(count)} steps to {to}, more than "
                f"time.max_steps = {case.time.max_steps:,}: use larger dt, or {raise_limit}"
            ),
        )


def _validate_steps_per_period(case: Case, period: float) -> None:
    """A periodic inlet's period must hold at least the schedule's largest step: a step over
    many heartbeats does work for each (the wall indices close one per heartbeat: 10⁵ per step
    for a period of 1e-8 s and 1 ms steps, 10²⁹⁷ for 1e-300 s, which ran until memory ran
    out), and samples the waveform at random phases anyway."""
    largest = largest_step(case)
    if 0 < period and period * (1 + 1e-12) < largest:
        raise ConfigError(
            "",
            "fluid.inlet.period",
            reason=(
                f"{period:g} s is shorter than the schedule's largest step (dt = {largest:g} s): "
                f"a step would span {largest / period:.3g} heartbeats; give the period in "
                f"seconds, or steps of at most {period:g} s (time.schedule)"
            ),
        )


def largest_step(case: Case) -> float:
    """The longest step (s) of the run's schedule up to its end (:func:`run_time`): a segment
    after the end is never stepped through, and one shorter than its dt is one step of its
    length (:func:`fsi.numerics.timestepping.steps`)."""
    run = run_time(case)
    largest, start = 0.0, 0.0
    for segment in run.schedule:
        stop = min(segment.until, run.end)
        if stop > start:
            largest = max(largest, min(segment.dt, stop - start))
        start = max(start, stop)
        if run.end <= segment.until:
            break
    return largest or max(segment.dt for segment in run.schedule)


def _validate_step_control(time: Time) -> None:
    """Adaptive steps need the second-order fluid scheme (the error estimate's order,
    fsi.numerics.timestepping.LocalError) and ``min_dt <= first_dt``."""
    if time.step_control != "adaptive":
        return
    if time.scheme != "bdf2":
        raise ConfigError(
            "",
            "time.step_control",
            reason=(
                "adaptive steps estimate a second-order scheme's error: they need "
                f"time.scheme bdf2, got {time.scheme!r}"
            ),
        )
    if time.adaptive.min_dt > time.adaptive.first_dt:
        raise ConfigError(
            "",
            "time.adaptive.min_dt",
            f"at most time.adaptive.first_dt = {time.adaptive.first_dt} s",
            time.adaptive.min_dt,
        )


def _validate_cycles(time: Time, period: float) -> None:
    """``time.cycles`` N > 1 needs an inlet ``period`` T > 0; with N >= 1 and T, ``time.end``
    is one heartbeat (T) or the whole run (N T), within 1e-9 relative (:class:`Time`)."""
    n = time.cycles
    if n > 1 and not period > 0:
        raise ConfigError(
            "",
            "time.cycles",
            reason=(
                f"{n} heartbeats need a periodic inlet (a pressure_table, pressure_file, "
                "flow_rate, flow_rate_table or flow_rate_file fluid.inlet with period > 0); "
                "this inlet does not repeat: use time.end instead"
            ),
        )
    if n >= 1 and period > 0:
        whole = n * period
        if not any(abs(time.end - t) <= SAME_TIME * t for t in (period, whole)):
            raise ConfigError(
                "",
                "time.end",
                reason=(
                    f"expected fluid.inlet.period = {period:g} s (one heartbeat) or "
                    f"time.cycles × period = {whole:g} s (the whole run) when time.cycles is "
                    f"{n}, got {time.end!r}; to end at time.end instead (a short try), set "
                    "time.cycles to 0 as well (--set time.cycles=0)"
                ),
            )


def _validate_element(case: Case) -> None:
    """Equal-order P1–P1 is stable only with the stabilized form's pressure terms, and only the
    fluid-only problem supports it (the interface maps pair P2 velocity nodes)."""
    if case.fluid.element != "p1p1":
        return
    if not case.fluid.supg:
        raise ConfigError(
            "",
            "fluid.element",
            "'p2p1' when fluid.supg is false (equal-order P1–P1 needs the stabilized form's"
            " PSPG term to hold the pressure)",
            case.fluid.element,
        )
    if case.structure.mode != "rigid":
        raise ConfigError(
            "",
            "fluid.element",
            "'p2p1' when structure.mode is not 'rigid' (the fluid–structure interface pairs the"
            " fluid's P2 velocity nodes with the solid's)",
            case.fluid.element,
        )


def _validate_solvers(case: Case) -> None:
    if (
        case.time.scheme == "steady"
        and case.structure.mode != "rigid"
        and case.structure.time_integration.scheme != "quasi_static"
    ):
        raise ConfigError(
            "",
            "structure.time_integration.scheme",
            "'quasi_static' when "
            "time.scheme is 'steady' (a steady fluid cannot load a structure "
            "with inertia)",
            case.structure.time_integration.scheme,
        )

    if case.time.scheme == "steady" and case.fluid.solver.linearization == "extrapolated":
        raise ConfigError(
            "",
            "fluid.solver.linearization",
            "'newton' when time.scheme is 'steady' (there are no past steps to extrapolate)",
            case.fluid.solver.linearization,
        )

    if case.coupling.max_relaxation < case.coupling.initial_relaxation:
        raise ConfigError(
            "",
            "coupling.max_relaxation",
            f"at least coupling.initial_relaxation = {case.coupling.initial_relaxation}",
            case.coupling.max_relaxation,
        )

    _validate_robin(case)

    # Sub-solvers must be well below the coupling tolerance or the coupling stalls near it.
    for name in ("fluid", "structure"):
        rtol = getattr(case, name).solver.rtol
        if rtol > case.coupling.tolerance / 10:
            raise ConfigError(
                "",
                f"{name}.solver.rtol",
                f"at most coupling.tolerance / 10 = {case.coupling.tolerance / 10:g}",
                rtol,
            )


def _validate_robin(case: Case) -> None:
    """Robin–Neumann's α from the wall (fsi/coupled/robin.py) needs a circular vessel: a plane
    wall has no hoop stiffness, and its inertia alone gives an α far below the wall's response
    (measured: the plane stenosis' 1,200 Pa s/m made the fluid diverge; 1e5–1e7 converged)."""
    coupling = case.coupling
    if coupling.scheme != "robin-neumann" or coupling.robin_coefficient is not None:
        return
    circular = is_axisymmetric(case.geometry) or dimension(case.geometry) == 3
    if case.structure.mode != "rigid" and not circular:
        raise ConfigError(
            "",
            "coupling.robin_coefficient",
            "a number (Pa s/m) for a plane model with coupling.scheme 'robin-neumann': only an "
            "axisymmetric or 3D vessel's wall gives it (docs/configuration.md, coupling)",
            "null",
        )


def _validate_inlet(case: Case) -> None:
    """A periodic table covers its period; a flow-rate inlet's profile can be built; an inlet
    formula is evaluated at t = 0, at every step time of the schedule and (Womersley) at the
    samples of its harmonics: one that fails (division by zero, log(0), overflow, ...) is
    refused now, not mid-run."""
    inlet = case.fluid.inlet
    if isinstance(inlet, TABLE_INLETS):
        _validate_period(inlet)
    if isinstance(inlet, FLOW_RATE_INLETS):
        _validate_profile(case)
    if isinstance(inlet, InletPressure):
        _validate_formula(time_function(inlet.formula), [step.t for step in steps(case.time)])
    elif isinstance(inlet, InletFlowRate):
        samples = sample_times(inlet.period) if inlet.profile == "womersley" else []
        _validate_formula(
            periodic(time_function(inlet.formula), inlet.period),
            [*(step.t for step in steps(case.time)), *samples],
        )


def _validate_formula(law, times) -> None:
    """Refuse ``fluid.inlet.formula`` unless ``law`` (its function of t) evaluates at t = 0
    and at ``times`` (s)."""
    try:
        law(0.0)
        for t in times:
            law(t)
    except FormulaError as e:
        raise ConfigError(
            "", "fluid.inlet.formula", reason=f"evaluation fails at t = {e.t:.6g} s ({e.reason})"
        ) from None


def _validate_profile(case: Case) -> None:
    """A ``womersley`` profile needs a period and a constant viscosity
    (:func:`fsi.config.rheology_section.womersley_viscosity`)."""
    inlet = case.fluid.inlet
    if inlet.profile != "womersley":
        return
    if not inlet.period > 0:
        raise ConfigError(
            "",
            "fluid.inlet.profile",
            reason="'womersley' needs fluid.inlet.period > 0 (s): the profile is built from "
            "the harmonics of one period of Q(t); give the period or use 'parabolic'",
        )
    if womersley_viscosity(case.fluid.rheology) is None:
        raise ConfigError(
            "",
            "fluid.inlet.profile",
            reason="'womersley' needs a constant viscosity (newtonian, or mu_inf of carreau, "
            f"carreau_yasuda, cross), not fluid.rheology.model "
            f"'{case.fluid.rheology.model}': use 'parabolic'",
        )


def _validate_period(inlet) -> None:
    """A periodic table (:data:`~fsi.config.fluid_section.TABLE_INLETS`) must cover one period:
    first t <= 0 and last t >= period."""
    period = inlet.period
    first, last = inlet.table[0][0], inlet.table[-1][0]
    if period > 0 and not (first <= 0 <= period <= last):
        rows = (
            f"the rows of {inlet.file}"
            if isinstance(inlet, WAVEFORM_FILES)
            else "fluid.inlet.table"
        )
        shown_first, _ = _apart(first, 0.0)
        shown_last, shown_period = _apart(last, period)
        raise ConfigError(
            "",
            "fluid.inlet.period",
            reason=(
                f"{rows} cover t in [{shown_first}, {shown_last}] s, not the whole period "
                f"[0, {shown_period}] s (the first t must be <= 0 and the last >= period)"
            ),
        )


def _apart(a: float, b: float) -> tuple[str, str]:
    """``a`` and ``b`` written with as few digits as tell them apart (``1`` and ``1.0000001``,
    not ``1`` and ``1``): a message comparing two numbers must not show them equal."""
    for digits in range(6, 18):
        shown = f"{a:.{digits}g}", f"{b:.{digits}g}"
        if shown[0] != shown[1] or a == b:
            return shown
    return repr(a), repr(b)


CUT_STEP = 0.1
"""A run whose end cuts its last step to less than this fraction of the schedule's ``dt``
is warned of (:func:`cautions`)."""


def _cut_last_step(case: Case) -> list[str]:
    """A caution when the run's end cuts its last step far below its segment's ``dt``
    (``--set time.end=0.002`` on a case of 0.5 s steps makes its one step 250 times shorter,
    which a coupled case set up for its ``dt`` may not converge at: the fluid's added mass on
    the wall grows as the step shrinks)."""
    run = run_time(case)
    start = 0.0
    for i, segment in enumerate(run.schedule):
        if run.end <= segment.until * (1 + 1e-12):
            span = run.end - start
            last = span - math.floor(span / segment.dt * (1 + SAME_TIME)) * segment.dt
            if last <= SAME_TIME * segment.dt or last >= CUT_STEP * segment.dt:
                return []
            where = f"time.schedule[{i}]" if run is case.time else "the heartbeat's schedule"
            return [
                f"time.end = {run.end:g} s cuts the last step of {where} (dt = {segment.dt:g} s) "
                f"to {last:.3g} s, {segment.dt / last:.3g} times shorter: a case set up for its "
                "dt may not converge at such a step (a coupled one: the fluid's added mass on "
                "the wall grows as the step shrinks); give steps that fit, --set "
                f"'time.schedule=[{{until: {run.end:g}, dt: ...}}]'"
            ]
        start = max(start, segment.until)
    return []


STEPS_PER_PERIOD = 4
"""Fewer steps than this per period of a periodic inlet sample its waveform too coarsely to
follow it (it is aliased): :func:`cautions` says so."""


def cautions(case: Case) -> list[str]:
    """What is valid in ``case`` but probably not meant, one message each (``fsi check`` and
    ``fsi run`` print them as warnings): a last step cut by the end to less than
    :data:`CUT_STEP` of its ``dt``; a periodic inlet whose period holds fewer than
    :data:`STEPS_PER_PERIOD` of the schedule's largest steps."""
    found = _cut_last_step(case)
    period = heartbeat_period(case)
    largest = largest_step(case)
    if 0 < period < STEPS_PER_PERIOD * largest:
        found.append(
            f"fluid.inlet.period = {period:g} s holds {period / largest:.3g} of the schedule's "
            f"largest steps (dt = {largest:g} s): a waveform sampled fewer than "
            f"{STEPS_PER_PERIOD} times a period is aliased; is the period in seconds?"
        )
    return found
