"""Running a case: the time loop (:mod:`.simulation`), the steppers it drives, one per kind of
run (:mod:`.steppers`) and their local time errors for adaptive steps (:mod:`.time_errors`),
the run's files (:mod:`.outputs`), how a run stops early (:mod:`.errors`), checkpoints and
restarts (:mod:`.checkpoint`, the state's arrays :mod:`.state_arrays`), parameter sweeps
(:mod:`.sweep`, as Slurm job arrays :mod:`.slurm`), and ``fsi run``'s and ``fsi sweep``'s
orchestration under the command line: one run with its checks, messages and exit status
(:mod:`.launch`), stopping on a signal (:mod:`.signals`) and the sweep's dispatch
(:mod:`.sweep_command`).
"""
