"""Meshes: built-in grids, gmsh geometries and mesh files, tagged with Γ_C and Γ_D, and their h."""
