"""The physics on one mesh: the tagged gmsh mesh (:mod:`.mesh`), the fluid (:mod:`.fluid`,
its viscosity laws :mod:`.rheology` and outlet models :mod:`.outlets`), the structure
(:mod:`.solid` and its laws :mod:`.materials`) and the ALE mesh motion (:mod:`.mesh_motion`).
"""
