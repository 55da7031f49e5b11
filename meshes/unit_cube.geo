// Unit cube (0,1)^3, meshed unstructured. Gamma_C = the bottom face z = 0; Gamma_D = the other five.
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 1, 1, 1};
boundary[] = Boundary{ Volume{1}; };
bottom[] = Surface In BoundingBox{-0.1, -0.1, -0.1, 1.1, 1.1, 0.1};
others[] = boundary[];
others[] -= bottom[];
Physical Surface("contact") = {bottom[]};
Physical Surface("dirichlet") = {others[]};
Physical Volume("domain") = {1};
