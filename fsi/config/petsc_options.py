"""PETSc options a case file may set: an allow-list, since PETSc options can run code (a
Python preconditioner type) and write files (viewers, monitors, logs)."""

from __future__ import annotations

import re

from fsi.config.reader import ConfigError, shorten

# Sub-solver prefixes inside one solver's options: the blocks of block Jacobi / ASM (sub_),
# the redundant PC, multigrid levels, fieldsplit blocks and a smoother's eigenvalue estimator.
_PETSC_SUBSOLVER = (
    r"(?:(?:sub|redundant|mg_coarse|mg_levels(?:_[0-9]+)?|fieldsplit_[a-z0-9]+"
    r"|esteig)_)*"
)

_PETSC_OPTIONS = (
    # Krylov method: type, tolerances, iteration limits, restart lengths
    r"ksp_(?:type|rtol|atol|divtol|max_it|norm_type|pc_side|initial_guess_nonzero"
    r"|error_if_not_converged|reuse_preconditioner|gmres_restart|gcr_restart"
    r"|gmres_modifiedgramschmidt|gmres_cgs_refinement_type|richardson_scale"
    r"|chebyshev_eigenvalues|chebyshev_esteig)",
    # preconditioner type; LU / ILU / Cholesky factorisations and the package that does them
    r"pc_(?:type|factor_mat_solver_type|factor_mat_ordering_type|factor_levels|factor_fill"
    r"|factor_shift_type|factor_shift_amount|factor_nonzeros_along_diagonal"
    r"|factor_pivot_in_blocks|jacobi_type|sor_omega|sor_its|sor_symmetric|asm_overlap|asm_type"
    r"|bjacobi_blocks)",
    # MUMPS (not ICNTL 1-4: output streams and print level; not 22: out-of-core files; 37, 48
    # and 58 need PETSc >= 3.20, older ones ignore them)
    r"mat_mumps_icntl_(?:6|7|8|10|11|12|13|14|23|24|25|27|28|29|35|36|37|38|48|58)",
    r"mat_mumps_cntl_[1-57]",
    r"mat_superlu_dist_(?:rowperm|colperm|equil|replacetinypivot|iterrefine)",
    # hypre BoomerAMG
    r"pc_hypre_type",
    r"pc_hypre_boomeramg_(?:strong_threshold|coarsen_type|interp_type|agg_nl|agg_num_paths"
    r"|max_iter|tol|max_levels|truncfactor|p_max|max_row_sum|cycle_type|relax_type_(?:all|down"
    r"|up|coarse)|grid_sweeps_(?:all|down|up|coarse)|relax_weight_all|outer_relax_weight_all"
    r"|nodal_coarsen|vec_interp_variant|numfunctions|measure_type|no_cf|smooth_type"
    r"|smooth_num_levels)",
    # GAMG and geometric/algebraic multigrid cycles
    r"pc_gamg_(?:type|threshold|threshold_scale|agg_nsmooths|square_graph|aggressive_coarsening"
    r"|coarse_eq_limit|process_eq_limit|reuse_interpolation|repartition"
    r"|esteig_ksp_type|esteig_ksp_max_it|use_sa_esteig|asm_use_agg"
    r"|use_parallel_coarse_grid_solver)",
    r"pc_mg_(?:levels|cycle_type|type|smoothup|smoothdown|galerkin|distinct_smoothup)",
    # fieldsplit and Schur complements
    r"pc_fieldsplit_(?:type|schur_fact_type|schur_precondition|schur_scale|detect_saddle_point"
    r"|block_size|diag_use_amat|off_diag_use_amat|[a-z0-9]+_fields)",
)
_PETSC_ALLOWED = re.compile(_PETSC_SUBSOLVER + "(?:" + "|".join(_PETSC_OPTIONS) + ")")

# Why a name is refused: patterns (searched in the lower-case name) of dangerous options.
_PETSC_REFUSED = (
    ("python", "a Python type imports and runs code the configuration names"),
    ("view", "viewers write to any file their value names (ascii:/path)"),
    ("monitor", "monitors write to any file their value names"),
    ("options", "options files and aliases read or inject other options"),
    (r"mat_mumps_icntl_[1-4]$", "MUMPS ICNTL 1-4 choose output streams and printing"),
    (r"mat_mumps_icntl_22$", "MUMPS ICNTL 22 writes out-of-core files"),
    ("print", "printing options write output"),
    ("log", "logging options write files"),
    ("dump", "dump options write files"),
    ("draw", "drawing options open windows or write files"),
)
_PETSC_TYPE_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]{0,63}")
_HYPRE_NAMES = frozenset(
    (
        "Jacobi",
        "sequential-Gauss-Seidel",
        "seqboundary-Gauss-Seidel",
        "SOR/Jacobi",
        "backward-SOR/Jacobi",
        "symmetric-SOR/Jacobi",
        "l1scaled-SOR/Jacobi",
        "Gaussian-elimination",
        "l1-Gauss-Seidel",
        "backward-l1-Gauss-Seidel",
        "CG",
        "Chebyshev",
        "FCF-Jacobi",
        "l1scaled-Jacobi",
        "CLJP",
        "Ruge-Stueben",
        "modifiedRuge-Stueben",
        "Falgout",
        "PMIS",
        "HMIS",
        "classical",
        "direct",
        "multipass",
        "multipass-wts",
        "ext+i",
        "ext+i-cc",
        "standard",
        "standard-wts",
        "FF",
        "FF1",
        "ext",
        "ext-mm",
        "ext+i-mm",
        "ext+e-mm",
    )
)
"""BoomerAMG's smoother, coarsening and interpolation names: fixed words of PETSc's hypre
interface, accepted although they contain ``/``, ``-`` or ``+``."""
_NUMBER = r"[-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]+)?"
_PETSC_NUMBERS = re.compile(f"{_NUMBER}(?:,{_NUMBER}){{0,63}}")  # "0.01", "0,1", "0.1,1.1"


def check_petsc_options(options: dict[str, str | int | float], key: str) -> None:
    """Raise :class:`ConfigError` naming ``key.<name>`` unless every option is on the allow-list.

    A configuration sets PETSc options under its solver's prefix (``fluid_``, ``solid_``,
    ``mesh_``), and PETSc options can run code (``pc_type: python`` with
    ``pc_python_type: module.Attr``) or write any file (``ksp_view: ascii:/path``). Allowed
    names (case-insensitive, as PETSc's; optionally behind sub-solver prefixes ``sub_``,
    ``redundant_``, ``mg_levels_[N_]``, ``mg_coarse_``, ``fieldsplit_<name>_``, ``esteig_``):
    Krylov types, tolerances, iteration limits and restarts; PC types and factorisations;
    MUMPS ICNTL/CNTL tuning (not its output streams or out-of-core files), SuperLU_dist;
    hypre BoomerAMG, GAMG, multigrid and fieldsplit/Schur tuning (``_PETSC_OPTIONS``). Allowed
    values: finite numbers, numbers as text or comma-separated lists of them, and type names
    of letters, digits and ``_`` (not ``python``).
    """
    for name, value in options.items():
        sub = f"{key}.{name}"
        lower = name.lower()
        if len(name) > 100 or not re.fullmatch(r"[a-z0-9_]+", lower):
            raise ConfigError(
                "",
                shorten(sub),
                reason="not a PETSc option name: letters, "
                "digits and _ only, without the leading '-' (the prefix is added)",
            )
        for pattern, why in _PETSC_REFUSED:
            if re.search(pattern, lower):
                raise ConfigError("", sub, reason=f"refused PETSc option: {why}")
        if not _PETSC_ALLOWED.fullmatch(lower):
            raise ConfigError(
                "",
                sub,
                reason="not an allowed PETSc option (solver and "
                "preconditioner types, tolerances, iteration limits and tuning: "
                "the list is in docs/configuration.md)",
            )
        if isinstance(value, str) and value not in _HYPRE_NAMES:
            if "python" in value.lower():
                raise ConfigError(
                    "",
                    sub,
                    reason=f"refused value {shorten(repr(value))}: a "
                    "Python type imports and runs code the configuration names",
                )
            if any(c in value for c in ":/\\~"):
                raise ConfigError(
                    "",
                    sub,
                    reason=f"refused value {shorten(repr(value))}: no "
                    "file paths or viewer specifications",
                )
            if not (_PETSC_TYPE_NAME.fullmatch(value) or _PETSC_NUMBERS.fullmatch(value)):
                raise ConfigError(
                    "",
                    sub,
                    "a type name (letters, digits, _), a number or comma-separated numbers",
                    value,
                )
    check_installed(options, key)


_EXTERNAL_PACKAGES = {
    "hypre": "hypre",
    "ml": "ml",
    "spai": "spai",
    "parms": "parms",
    "h2opus": "h2opus",
    "hpddm": "hpddm",
    "mumps": "mumps",
    "superlu_dist": "superlu_dist",
    "superlu": "superlu",
    "umfpack": "suitesparse",
    "cholmod": "suitesparse",
    "klu": "suitesparse",
    "pastix": "pastix",
    "strumpack": "strumpack",
    "mkl_pardiso": "mkl_pardiso",
    "mkl_cpardiso": "mkl_cpardiso",
    "cusparse": "cuda",
}
"""A preconditioner or factorisation type → the external package PETSc needs for it."""


def check_installed(options: dict[str, str | int | float], key: str) -> None:
    """Raise :class:`ConfigError` naming ``key.<name>`` for a Krylov, preconditioner or
    factorisation type the installed PETSc does not have: not one of its types, or one whose
    external package it was built without (e.g. ``pc_type: hypre`` or
    ``pc_factor_mat_solver_type: mumps`` on a PETSc without hypre or MUMPS), so that a
    preset copied from docs/3d.md fails before any solve, not in its first one. Imports
    petsc4py (only when such an option is set)."""
    kinds = ("ksp_type", "pc_type", "pc_factor_mat_solver_type")
    typed = {n: v for n, v in options.items() if n.lower().endswith(kinds)}
    if not typed:
        return
    from petsc4py import PETSc

    for name, value in typed.items():
        lower, text = name.lower(), str(value).lower()
        sub = f"{key}.{name}"
        if lower.endswith(("pc_type", "ksp_type")):
            family = PETSc.PC.Type if lower.endswith("pc_type") else PETSc.KSP.Type
            known = {v for k, v in vars(family).items() if not k.startswith("_")}
            if text not in known:
                what = "preconditioner" if family is PETSc.PC.Type else "Krylov solver"
                raise ConfigError(
                    "", sub, reason=f"{value!r} is not a {what} type of the installed PETSc"
                )
        package = _EXTERNAL_PACKAGES.get(text)
        if lower.endswith("pc_factor_mat_solver_type") and text != "petsc" and package is None:
            raise ConfigError(
                "", sub, reason=f"{value!r} is not a factorisation package PETSc knows"
            )
        if package is not None and not PETSc.Sys.hasExternalPackage(package):
            raise ConfigError(
                "",
                sub,
                reason=f"{value!r} needs PETSc built with {package}, which the installed "
                f"PETSc {'.'.join(map(str, PETSc.Sys.getVersion()))} is not",
            )
