"""Reproduce the study (docs/model.md §4, §6): its four configurations on the coarse and
the fine mesh, the whole heartbeat, with the resolved schedule of the shipped configs, plus the
study's printed schedule (5 ms to 0.4 s, 10 ms to 0.8 s) on the coarse mesh; the runs of the
:data:`ANALYSES` that isolate why fsi differs from the study's tables; then write docs/study.md,
docs/study_tables.csv, the runs' summaries (docs/study_runs/) and the figures.

    scripts/reproduce_study.py                  # run what is missing, then write the document
    scripts/reproduce_study.py --only coarse    # the study's coarse runs only (a few minutes)
    scripts/reproduce_study.py --only analyses --analysis damping --ranks 1
    scripts/reproduce_study.py --document-only  # rewrite the document from the runs there are
                                                # (or their committed summaries)

Finished runs (summary.json with the run's end time) are skipped, stopped ones (a checkpoint)
resumed with ``--restart``; so the script can be stopped and run again at any point. Each run
is ``mpirun -n RANKS fsi run configs/<case>.yaml --out RUNS/<name>`` (default 2 ranks, the
machine's cores), one at a time; a sweep is ``fsi sweep``, which skips its finished runs.
"""

from __future__ import annotations

import argparse
import functools
import json
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from fsi import config
from fsi.run import child_runs
from fsi.study.analyses import effective_length
from fsi.study.pressure_analyses import P10_VARIANTS

ROOT = Path(__file__).resolve().parents[2]

CASES = [
    "stenosis_fixed_newtonian",
    "stenosis_fixed_carreau",
    "stenosis_moving_newtonian",
    "stenosis_moving_carreau",
]
PRINTED_SCHEDULE = "time.schedule=[{until: 0.4, dt: 0.005}, {until: 0.8, dt: 0.01}]"
HALVED_SCHEDULE = (
    "time.schedule=[{until: 0.05, dt: 1.25e-4}, {until: 0.1, dt: 5.0e-4}, {until: 0.8, dt: 2.5e-3}]"
)
"""The shipped configs' schedule with every step halved."""
LARGE_STEPS = "time.schedule=[{until: 0.005, dt: 2.5e-4}, {until: 0.1, dt: 5.0e-3}]"
"""The pulse resolved, then the study's 5 ms steps."""


@dataclass(frozen=True)
class StudyRun:
    """One run of the study: a shipped case on a mesh level, with its schedule; or, with a
    ``label``, a run of one of the :data:`ANALYSES` that isolates a difference from the study
    (the case with further ``sets``, up to ``end``)."""

    case: str
    level: str  # coarse | medium | fine | finest
    schedule: str = "resolved"  # resolved (the config's) | printed (the study's)
    sets: tuple[str, ...] = ()
    label: str = ""
    end: float = 0.8

    @property
    def name(self) -> str:
        if self.label:
            return self.label
        suffix = "" if self.schedule == "resolved" else "_printed"
        return f"{self.case.removeprefix('stenosis_')}_{self.level}{suffix}"

    @property
    def overrides(self) -> list[str]:
        sets = [f"mesh.level={self.level}"]
        if self.schedule == "printed":
            sets.append(PRINTED_SCHEDULE)
        if self.end != 0.8:
            sets.append(f"time.end={self.end:g}")
        return sets + list(self.sets)

    @property
    def config(self) -> Path:
        return ROOT / "configs" / f"{self.case}.yaml"


@dataclass(frozen=True)
class StudySweep:
    """``fsi sweep`` of a shipped case on a mesh level up to ``end``: every combination of the
    ``vary`` values (key, values), in the folder ``label``."""

    case: str
    level: str
    vary: tuple[tuple[str, tuple[float, ...]], ...]
    label: str
    end: float = 0.8

    @property
    def name(self) -> str:
        return self.label

    @property
    def config(self) -> Path:
        return ROOT / "configs" / f"{self.case}.yaml"

    def command(self, out: Path) -> list[str]:
        """The ``fsi sweep`` command (it skips the runs it finished before)."""
        cmd = [sys.executable, "-m", "fsi", "sweep", str(self.config), "--out", str(out)]
        for key, values in self.vary:
            cmd += ["--vary", f"{key}=" + ",".join(f"{v:g}" for v in values)]
        return cmd + ["--set", f"mesh.level={self.level}", "--set", f"time.end={self.end:g}"]


RUNS = (
    [StudyRun(c, "coarse", "resolved") for c in CASES]
    + [StudyRun(c, "coarse", "printed") for c in CASES]
    + [StudyRun(c, "fine", "resolved") for c in reversed(CASES)]
)  # the moving wall first


@functools.cache
def _shipped(case: str = "stenosis_fixed_newtonian") -> config.Case:
    """A shipped case's configuration (fsi.config): the settings the analyses scale or convert
    are read from it, not restated."""
    return config.load(ROOT / "configs" / f"{case}.yaml")


def _scaled_pulse(length: float) -> float:
    """The pulse amplitude (Pa) whose impulse moves the blood column of a segment ``length``
    long as fast as the shipped pulse moves the shipped segment's (the rigid-column estimate,
    fsi/study/analyses.py): amplitude ∝ effective length."""
    shipped = _shipped()
    g = shipped.geometry
    return (
        shipped.fluid.inlet.amplitude
        * effective_length(length, g.stenosis_length, g.stenosis_degree)
        / effective_length(g.length, g.stenosis_length, g.stenosis_degree)
    )


EARLIER_SETTINGS = (
    "fluid.supg=false",
    "fluid.inlet_open_boundary=same",
    "fluid.normal_flow=true",
    "fluid.inflow_stabilization=0",
    "fluid.outlet.backflow_form=full",
)
"""The fluid as the study's configs set it before the physiological-flow settings (docs/study.md
at git 3d90d70): the Galerkin form, the inlet in the outlet's do-nothing form with its velocity
held normal and no term on re-entering blood, the outlet's backflow term in its ``full``
form."""


def _plane_stress() -> tuple[str, ...]:
    """The shipped regions' moduli (E, ν of the shipped configuration) as the plane-strain
    equivalent of plane stress (SVK): E (1 + 2ν) / (1 + ν)², ν / (1 + ν)."""
    materials = {r: getattr(_shipped().structure, r) for r in ("wall", "cap", "lipid")}
    return tuple(
        s
        for region, m in materials.items()
        for e, nu in [(m.young_modulus, m.poisson_ratio)]
        for s in (
            f"structure.{region}.young_modulus={e * (1 + 2 * nu) / (1 + nu) ** 2:.6g}",
            f"structure.{region}.poisson_ratio={nu / (1 + nu):.6g}",
        )
    )


def _tau(tau: float) -> tuple[str, ...]:
    """Kelvin–Voigt relaxation time ``tau`` (s) in every structure region."""
    return tuple(f"structure.{r}.viscous_relaxation_time={tau:g}" for r in ("wall", "cap", "lipid"))


ANALYSES = {
    # 1. The fixed wall's compliance: the plaque's shape the study leaves open, and the reading
    #    of "fixed wall" as the wall deforming with its outer surface held.
    "compliance": [
        StudySweep(
            "stenosis_fixed_newtonian",
            "coarse",
            vary=(
                ("geometry.stenosis_degree", (0.3, 0.4, 0.5, 0.6, 0.7)),
                ("geometry.cap_thickness", (0.0001, 0.0002, 0.0005)),
                ("geometry.lipid_length", (0.004, 0.006)),
            ),
            label="compliance/plaque_shape",
            end=0.01,
        ),
        StudyRun(
            "stenosis_moving_newtonian",
            "coarse",
            sets=("structure.support.stiffness=1e12",),
            label="compliance/wall_held_outside",
            end=0.1,
        ),
    ]
    + [
        # not a reading of the study (it prints 1.6 MPa for the plaque): what a softer lipid
        # pool would do
        StudyRun(
            "stenosis_fixed_newtonian",
            "coarse",
            sets=(f"structure.lipid.young_modulus={e:g}",),
            label=f"compliance/lipid_modulus={e:g}",
            end=0.01,
        )
        for e in (1.6e5, 1.6e4)
    ],
    # ... and the 2D model read as plane stress: for St. Venant-Kirchhoff the same in-plane law as
    # plane strain with nu' = nu / (1 + nu), E' = E (1 + 2 nu) / (1 + nu)^2.
    "plane_stress": [
        StudyRun(
            case,
            "coarse",
            sets=_plane_stress(),
            label=f"plane_stress/{case.removeprefix('stenosis_')}",
        )
        for case in ("stenosis_fixed_newtonian", "stenosis_moving_newtonian")
    ],
    # 7. The one most-plausible reading (docs/study.md, PLAUSIBLE in fsi/study/plausible.py):
    #    plane stress, everything else as shipped, all four configurations.
    "plausible": [
        StudyRun(
            case,
            level,
            sets=_plane_stress(),
            label=f"plausible/{case.removeprefix('stenosis_')}_{level}",
        )
        for level in ("coarse", "fine")
        for case in CASES
    ],
    # 2. The moving wall's damping: which relaxation time makes the wall quasi-static by 10 ms.
    "damping": [
        StudyRun(
            "stenosis_moving_newtonian",
            "coarse",
            sets=_tau(tau),
            label=f"damping/tau={tau:g}",
            end=0.1,
        )
        for tau in (1e-3, 4e-3, 1e-2, 4.3e-2)
    ]
    + [
        # no inertia: the wall in equilibrium with the blood's load at every step
        StudyRun(
            "stenosis_moving_newtonian",
            "coarse",
            sets=("structure.time_integration={scheme: quasi_static}",),
            label="damping/quasi_static",
            end=0.1,
        ),
        # the pulse resolved, then the study's 5 ms steps with the most numerical dissipation
        StudyRun(
            "stenosis_moving_newtonian",
            "coarse",
            sets=(
                "time.schedule=[{until: 0.005, dt: 2.5e-4}, {until: 0.1, dt: 5.0e-3}]",
                "structure.time_integration.spectral_radius=0",
            ),
            label="damping/large_steps",
            end=0.1,
        ),
    ],
    # 5. What the physiological-flow settings changed: the fine runs with the fluid's earlier
    #    settings, beside the shipped fine runs.
    "earlier": [
        StudyRun(
            case,
            "fine",
            sets=EARLIER_SETTINGS,
            label=f"earlier/{case.removeprefix('stenosis_')}_fine",
        )
        for case in CASES
    ],
    # 3. The inlet before the physiological-flow issue (do-nothing, velocity held normal).
    "inlet": [
        StudyRun(
            case,
            "coarse",
            sets=(
                "fluid.inlet_open_boundary=same",
                "fluid.normal_flow=true",
                "fluid.inflow_stabilization=0",
            ),
            label=f"inlet/{case.removeprefix('stenosis_')}_normal_flow",
        )
        for case in CASES
    ],
    # 3. The time scheme and the study's 5 ms steps after the resolved pulse.
    "steps": [
        StudyRun("stenosis_fixed_newtonian", "coarse", sets=sets, label=f"steps/{name}", end=0.1)
        for name, sets in (
            ("backward_euler", ("time.scheme=backward_euler",)),
            ("large_steps_bdf2", (LARGE_STEPS,)),
            ("large_steps_backward_euler", (LARGE_STEPS, "time.scheme=backward_euler")),
        )
    ],
    # 3b. What the fixed wall's p(10 ms) does not depend on, to 20 ms.
    "p10": [
        StudyRun("stenosis_fixed_newtonian", "coarse", sets=sets, label=f"p10/{name}", end=0.02)
        for name, (_, sets) in P10_VARIANTS.items()
    ],
    # 3c. The fluid's element: the study's code (COMSOL) discretises laminar flow with
    #     equal-order P1+P1 by default; fsi's P1-P1 is fluid-only, so the plaque is held rigid
    #     (which alone leaves p(10 ms) alone: the fixed wall's plaque moves by 0.05 um).
    "element": [
        StudyRun(
            "stenosis_fixed_newtonian",
            level,
            sets=("structure.mode=rigid", f"fluid.element={element}"),
            label=f"element/{element}_{level}",
            end=0.1,
        )
        for level in ("coarse", "fine")
        for element in ("p2p1", "p1p1")
    ],
    # 4. The stenosis degree behind the velocity.
    "degree": [
        StudyRun(
            "stenosis_fixed_newtonian",
            "coarse",
            sets=(f"geometry.stenosis_degree={d:g}",),
            label=f"degree/degree={d:g}",
            end=0.1,
        )
        for d in (0.3, 0.35, 0.4, 0.45, 0.5, 0.55)
    ],
    # 6. The outlet 1 and 2 cm further downstream. A pressure pulse accelerates the whole blood
    #    column, so a longer one would move slower: the pulse is scaled by the effective length
    #    (the same rigid-column velocity, docs/study.md item 4), and only the fixed wall is
    #    compared (a moving wall clamped further apart is a softer wall); the moving wall
    #    lengthened as it is shows why.
    "downstream": [
        StudyRun(
            "stenosis_fixed_newtonian",
            "coarse",
            sets=(
                f"geometry.length={0.02 + extra:g}",
                "geometry.stenosis_centre=0.01",
                f"fluid.inlet.amplitude={_scaled_pulse(0.02 + extra):.6g}",
            ),
            label=f"downstream/fixed_newtonian_plus_{100 * extra:g}cm",
        )
        for extra in (0.01, 0.02)
    ]
    + [
        StudyRun(
            "stenosis_moving_newtonian",
            "coarse",
            sets=(f"geometry.length={0.02 + extra:g}", "geometry.stenosis_centre=0.01"),
            label=f"downstream/moving_newtonian_plus_{100 * extra:g}cm",
        )
        for extra in (0.01, 0.02)
    ],
    # Mesh and step convergence of the stress maxima the findings rest on (all reached by 12 ms):
    # the medium and finest meshes beside the coarse and fine runs, and the fine mesh with
    # every step halved, each to 20 ms.
    "convergence": [
        StudyRun(
            case, level, label=f"convergence/{case.removeprefix('stenosis_')}_{level}", end=0.02
        )
        for case in ("stenosis_fixed_newtonian", "stenosis_moving_newtonian")
        for level in ("medium", "finest")
    ]
    + [
        StudyRun(
            case,
            "fine",
            sets=(HALVED_SCHEDULE,),
            label=f"convergence/{case.removeprefix('stenosis_')}_fine_dt_halved",
            end=0.02,
        )
        for case in ("stenosis_fixed_newtonian", "stenosis_moving_newtonian")
    ],
}
"""The runs that isolate the causes of the differences from the study (docs/study.md, one
section each), on the coarse mesh (the fixed wall's displacement is within 0.5 % of the fine
mesh's and the velocity within 0.4 %), but the convergence runs on the other meshes and the
earlier settings' and the most-plausible reading's also on the fine one."""


def state(out: Path, end: float = 0.8) -> str:
    """``finished`` (at ``end``), ``stopped`` (a checkpoint to resume from) or ``new``."""
    summary = out / "summary.json"
    if summary.is_file():
        data = json.loads(summary.read_text())
        if abs(data.get("end_time_s", 0.0) - end) < 1e-9:
            return "finished"
    if (out / "checkpoint" / "checkpoint.json").is_file():
        return "stopped"
    return "new"


def fsi_command(run: StudyRun | StudySweep, out: Path, ranks: int) -> list[str]:
    """``fsi sweep`` of a sweep; else ``fsi run``, resuming a stopped run or overwriting a
    stale folder; under ``mpirun`` for more than one rank."""
    if isinstance(run, StudySweep):
        fsi = run.command(out)
    else:
        fsi = [sys.executable, "-m", "fsi", "run", str(run.config), "--out", str(out)]
        for s in run.overrides:
            fsi += ["--set", s]
        if state(out, run.end) == "stopped":
            fsi += ["--restart", str(out)]
        elif out.exists():
            fsi += ["--overwrite"]
    return ["mpirun", "-n", str(ranks), "--oversubscribe", *fsi] if ranks > 1 else fsi


def run_all(runs: list[StudyRun | StudySweep], folder: Path, ranks: int) -> None:
    for run in runs:
        out = folder / run.name
        status = "sweep" if isinstance(run, StudySweep) else state(out, run.end)
        if status == "finished":
            print(f"{run.name}: finished, skipped", flush=True)
            continue
        print(f"{run.name}: {'resuming' if status == 'stopped' else 'starting'}", flush=True)
        tic = time.perf_counter()
        log = folder / f"{run.name}.log"
        log.parent.mkdir(parents=True, exist_ok=True)
        with log.open("a") as f:
            code = subprocess.call(
                fsi_command(run, out, ranks),
                stdout=f,
                stderr=subprocess.STDOUT,
                cwd=ROOT,
                env=child_runs.environment(),
            )
        print(
            f"{run.name}: exit {code} after {time.perf_counter() - tic:.0f} s (log {log})",
            flush=True,
        )


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--runs",
        type=Path,
        default=ROOT / "results" / "study",
        help="folder of the run folders (default results/study)",
    )
    parser.add_argument("--ranks", type=int, default=2)
    parser.add_argument(
        "--only",
        choices=["coarse", "fine", "analyses"],
        help="run one mesh level of the study's runs only, or the analyses only",
    )
    parser.add_argument(
        "--analysis",
        choices=list(ANALYSES),
        action="append",
        help="with --only analyses: this one (repeatable; default all)",
    )
    parser.add_argument(
        "--document-only",
        action="store_true",
        help="write docs/study.md from the runs there are; run nothing",
    )
    parser.add_argument("--docs", type=Path, default=ROOT / "docs")
    args = parser.parse_args(argv)
    analyses = [
        r
        for name, runs in ANALYSES.items()
        for r in runs
        if args.analysis is None or name in args.analysis
    ]
    if args.only == "analyses":
        runs = analyses
    else:
        runs = [r for r in RUNS if args.only is None or r.level == args.only]
        runs += analyses if args.only is None else []
    if not args.document_only:
        run_all(runs, args.runs, args.ranks)
    from fsi.study import document as study_document

    written = study_document.write(args.runs, RUNS, args.docs, ANALYSES)
    print(f"wrote {written}")
    return 0
