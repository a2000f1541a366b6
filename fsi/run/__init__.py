"""Running a case: the time loop (:mod:`.simulation`), the steppers it drives, one per kind of
run (:mod:`.steppers`) and their local time errors for adaptive steps (:mod:`.time_errors`),
the run's files (:mod:`.outputs`), how a run stops early (:mod:`.errors`), checkpoints and
restarts (:mod:`.checkpoint`, the state's arrays :mod:`.state_arrays`) and parameter sweeps
(:mod:`.sweep`).
"""
