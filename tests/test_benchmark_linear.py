"""scripts/benchmark_linear.py (docs/performance.md): it measures the Jacobians the study's Newton
iterations solve with, under the case's own solver and under another one asked for, and its
figures are those of the solves it made. Coarse, after 2 steps; on 1 and 2 ranks alike."""

import pytest

from fsi.performance import linear_solves as benchmark_linear

ITERATIVE = "ksp_type=cg pc_type=jacobi ksp_rtol=1e-10 ksp_max_it=20000"
FIELDSPLIT = (  # docs/3d.md's fluid preset: it needs the fluid's fields u and p
    "ksp_type=fgmres ksp_rtol=1e-10 ksp_max_it=400 pc_type=fieldsplit pc_fieldsplit_type=schur "
    "pc_fieldsplit_schur_fact_type=lower pc_fieldsplit_schur_precondition=selfp "
    "fieldsplit_u_ksp_type=preonly fieldsplit_u_pc_type=hypre "
    "fieldsplit_p_ksp_type=preonly fieldsplit_p_pc_type=hypre"
)


@pytest.fixture(scope="module")
def rows():
    tries = ["--try", "structure", ITERATIVE, "--try", "fluid", FIELDSPLIT]
    return benchmark_linear.main(["--level", "coarse", "--steps", "2", "--repeats", "3", *tries])


def test_every_system_under_every_solver(rows):
    assert [(r["system"], r["solver"]) for r in rows] == [
        ("fluid", "case"),
        ("fluid", FIELDSPLIT),
        ("structure", "case"),
        ("structure", ITERATIVE),
    ]
    fluid, _, structure, _ = rows
    assert fluid["dofs"] == 8814 and structure["dofs"] == 5554  # docs/performance.md's coarse


def test_the_case_solver_is_an_exact_lu(rows):
    for r in (rows[0], rows[2]):
        assert r["iterations"] == 1 and r["converged"]
        assert r["relative_residual"] < 1e-9, r
        assert r["factor_entries"] > 0  # MUMPS reported its factor
        assert 0 < r["solve_ms"] and 0 < r["refactor_ms"] and 0 < r["setup_s"]


def test_the_tried_solver_is_the_one_measured(rows):
    """Jacobi-preconditioned CG takes many iterations where the LU takes one, and has no factor."""
    r = rows[3]
    assert r["converged"] and r["iterations"] > 50, r
    assert r["factor_entries"] != r["factor_entries"]  # nan: no factorisation


def test_a_fieldsplit_preconditioner_gets_the_fluids_fields(rows):
    """The fluid's block preconditioner (PETSc cannot find u and p in the interleaved matrix
    itself: without the fields its set-up fails) converges to the tolerance asked."""
    r = rows[1]
    assert r["converged"] and 1 < r["iterations"] < 400, r
    assert r["relative_residual"] < 1e-8, r


def test_bad_options_are_refused():
    with pytest.raises(SystemExit):
        benchmark_linear.main(["--level", "coarse", "--try", "structure", "ksp_type"])


def test_the_case_own_solver_follows_the_config_overrides():
    """``--set`` changes the case's own solvers (where LU does not fit): its structure row is
    then Jacobi-preconditioned CG, not an LU."""
    options = "{ksp_type: cg, pc_type: jacobi, ksp_rtol: 1.0e-10, ksp_max_it: 20000}"
    rows = benchmark_linear.main(
        ["--level", "coarse", "--steps", "1", "--repeats", "1", "--systems", "structure"]
        + ["--set", f"structure.solver.petsc_options={options}"]
    )
    [r] = rows
    assert r["solver"] == "case" and r["converged"] and r["iterations"] > 50, r
    assert r["factor_entries"] != r["factor_entries"]  # nan: no factorisation
