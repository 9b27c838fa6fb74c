// A 2D plate 2 x 1 with a circular hole of radius 0.25 at (0.6, 0.5), linear triangles.
// Physical groups: "left" (x = 0), "right" (x = 2), "bottom" (y = 0), "top" (y = 1),
// "hole" (the circle), "plate" (the surface).
// Regenerate: gmsh -2 -format msh41 plate-with-hole.geo -o plate-with-hole.msh
SetFactory("OpenCASCADE");
lc = 0.04;
Rectangle(1) = {0, 0, 0, 2, 1};
Disk(2) = {0.6, 0.5, 0, 0.25};
BooleanDifference(3) = { Surface{1}; Delete; }{ Surface{2}; Delete; };
Mesh.CharacteristicLengthMax = lc;
eps = 1e-6;
Physical Curve("left") = Curve In BoundingBox{-eps, -eps, -eps, eps, 1 + eps, eps};
Physical Curve("right") = Curve In BoundingBox{2 - eps, -eps, -eps, 2 + eps, 1 + eps, eps};
Physical Curve("bottom") = Curve In BoundingBox{-eps, -eps, -eps, 2 + eps, eps, eps};
Physical Curve("top") = Curve In BoundingBox{-eps, 1 - eps, -eps, 2 + eps, 1 + eps, eps};
Physical Curve("hole") = Curve In BoundingBox{0.35 - eps, 0.25 - eps, -eps, 0.85 + eps, 0.75 + eps, eps};
Physical Surface("plate") = {3};
