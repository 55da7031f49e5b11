// A user's own mesh, as `mesh: {kind: file}` reads it: the quarter annulus 1 < r < 2, x > 0, y > 0.
// The physical group names are the user's choice; the config's `contact:` picks Γ_C among them
// (configs/gmsh/file-quarter-annulus.yaml: contact: inner_arc, a concave curved contact boundary).
// Made with:  python3 -c "import gmsh; gmsh.initialize(); gmsh.open('quarter_annulus.geo');
//   gmsh.option.setNumber('Mesh.MeshSizeFromPoints', 0); gmsh.option.setNumber('Mesh.MeshSizeMax', 0.25);
//   gmsh.model.mesh.generate(2); gmsh.write('quarter_annulus.msh'); gmsh.finalize()"
Point(1) = {0, 0, 0};
Point(2) = {1, 0, 0};
Point(3) = {2, 0, 0};
Point(4) = {0, 2, 0};
Point(5) = {0, 1, 0};
Line(1) = {2, 3};
Circle(2) = {3, 1, 4};
Line(3) = {4, 5};
Circle(4) = {5, 1, 2};
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};
Physical Curve("inner_arc") = {4};
Physical Curve("outer_arc") = {2};
Physical Curve("straight_sides") = {1, 3};
Physical Surface("annulus") = {1};
