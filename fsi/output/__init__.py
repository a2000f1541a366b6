"""What a run measures and writes, and what reads it back: the metrics of a step
(:mod:`.metrics`, :mod:`.columns`, :mod:`.wall_outputs`), the run's files (:mod:`.io`,
:mod:`.provenance`, :mod:`.paths`), reports and plots (:mod:`.report`, :mod:`.plot`,
:mod:`.wall_plot`, :mod:`.units`).
"""
