"""Running a case: the time loop (:mod:`.simulation`), the steppers it drives, one per kind of
run (:mod:`.steppers`), the run's files (:mod:`.outputs`), how a run stops early (:mod:`.stops`),
checkpoints and restarts (:mod:`.checkpoint`) and parameter sweeps (:mod:`.sweep`).
"""
