"""Newton's method (PETSc SNES) with its strategies, and moving a solution between meshes."""
