"""The coupled problem: the maps between the fluid's and the structure's interface dofs
(:mod:`.interface`), the fluid and the structure as interface solvers (:mod:`.adapters`), the
Dirichlet–Neumann loop with its accelerations and predictors (:mod:`.coupling`) and the
partitioned problem that joins them (:mod:`.partitioned`).
"""
