// A 3D block 2 x 1 x 1 with a cylindrical hole of radius 0.25 along z through (1, 0.5),
// linear tetrahedra. Physical groups: the faces "x0" "x1" "y0" "y1" "z0" "z1", "hole" (the
// cylinder), "solid" (the volume).
// Regenerate: gmsh -3 -format msh41 bracket.geo -o bracket.msh
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 2, 1, 1};
Cylinder(2) = {1, 0.5, 0, 0, 0, 1, 0.25};
BooleanDifference(3) = { Volume{1}; Delete; }{ Volume{2}; Delete; };
Mesh.CharacteristicLengthMax = 0.1;
eps = 1e-6;
Physical Surface("x0") = Surface In BoundingBox{-eps, -eps, -eps, eps, 1 + eps, 1 + eps};
Physical Surface("x1") = Surface In BoundingBox{2 - eps, -eps, -eps, 2 + eps, 1 + eps, 1 + eps};
Physical Surface("y0") = Surface In BoundingBox{-eps, -eps, -eps, 2 + eps, eps, 1 + eps};
Physical Surface("y1") = Surface In BoundingBox{-eps, 1 - eps, -eps, 2 + eps, 1 + eps, 1 + eps};
Physical Surface("z0") = Surface In BoundingBox{-eps, -eps, -eps, 2 + eps, 1 + eps, eps};
Physical Surface("z1") = Surface In BoundingBox{-eps, -eps, 1 - eps, 2 + eps, 1 + eps, 1 + eps};
Physical Surface("hole") = Surface In BoundingBox{0.75 - eps, 0.25 - eps, -eps, 1.25 + eps, 0.75 + eps, 1 + eps};
Physical Volume("solid") = {3};
