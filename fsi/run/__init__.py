"""Running a case: the steppers and the time loop (:mod:`.simulation`), checkpoints and
restarts (:mod:`.checkpoint`) and parameter sweeps (:mod:`.sweep`).
"""
