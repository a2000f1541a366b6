"""scripts/benchmark_fluid.py (docs/performance.md) runs through on the coarse mesh and prints
its two tables: the fluid solver's costs, with the residual as the solver evaluates it and with
its Dirichlet lifting assembled, and the Carreau Jacobian against the quadrature degree (each
degree a solver of its own: SUPG's held τ lives at the degree's points; the degree study once
failed with "Mismatch of tabulation points" when the degree was set on the form alone)."""

import logging

from mpi4py import MPI

from fsi.performance import fluid_speed as benchmark_fluid


def test_both_tables_are_printed(capsys):
    argv = ["--levels", "coarse", "--models", "carreau", "--steps", "1", "--repeats", "1"]
    assert benchmark_fluid.main([*argv, "--degrees", "2", "4"]) == 0
    if MPI.COMM_WORLD.rank != 0:  # rank 0 prints
        return
    lines = capsys.readouterr().out.splitlines()
    row = next(line.split() for line in lines if line.startswith("coarse "))
    assert row[:3] == ["coarse", "carreau", "8814"]
    F, F_lifted = float(row[6]), float(row[7])  # µs/dof, lifting skipped and assembled
    assert F > 0 and F_lifted > 0
    study = lines[lines.index(next(x for x in lines if x.startswith("Carreau Jacobian"))) :]
    degrees = {line.split()[0]: line.split() for line in study if line[:1].isdigit()}
    assert set(degrees) == {"2", "4"}
    assert float(degrees["4"][4]) == 1.0  # "× deg 4" of the reference degree
    assert any(line.startswith("auto (cell ") for line in study)


def test_importing_and_running_it_leaves_logging_alone():
    """The script silences INFO logging only when run as a script: a test running its main()
    once switched it off for the rest of the pytest process, and the run-log checks of
    tests/test_faults.py failed ("step 2/4" missing from run.log)."""
    assert logging.root.manager.disable < logging.INFO
