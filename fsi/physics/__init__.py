"""The physics on one mesh: the tagged gmsh mesh (:mod:`.mesh`); the fluid (:mod:`.fluid`, the
solver; :mod:`.fluid_residual`, its weak form; :mod:`.fluid_boundaries`, its boundary conditions,
:mod:`.fluid_boundary_terms`, what they add to the problem;
its viscosity laws :mod:`.rheology`, outlet models :mod:`.outlets` and inflow profiles
:mod:`.inflow_profiles`); the structure
(:mod:`.solid`, the solver; :mod:`.solid_residual`, its weak form; :mod:`.solid_stress`, its
stresses; its laws :mod:`.materials`) and the ALE mesh motion (:mod:`.mesh_motion`).
"""
