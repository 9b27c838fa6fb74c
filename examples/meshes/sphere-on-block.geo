// Hertz contact in 3D, quarter model (x >= 0, y >= 0, symmetric about both planes): a quarter of
// the lower half of a sphere of radius R = 1 (its flat top at z = 1, where the load acts)
// touching at the origin the block [0, 2] x [0, 2] x [-2, 0]; with half = 1 the half model
// (y >= 0 only: x in [-1, 1] and the block [-2, 2] x [0, 2] x [-2, 0], for loads along x). The
// bodies are meshed apart (no shared nodes) with tet4, finest near the contact point (size h),
// coarsest (size H) far from it. Physical groups: "sphere", "block" (volumes), "sphere_surface"
// (the contact surface), "sphere_top", "sphere_y0", "block_top", "block_y0", "block_bottom", and
// in the quarter model "sphere_x0", "block_x0".
// Regenerate: gmsh -3 -format msh41 sphere-on-block.geo -o sphere-on-block.msh
//             (finer: -setnumber h 0.01)
SetFactory("OpenCASCADE");
If (!Exists(h)) h = 0.03; EndIf
If (!Exists(H)) H = 0.4; EndIf
If (!Exists(half)) half = 0; EndIf
x0 = half ? -1 : 0;
Sphere(1) = {0, 0, 1, 1};
Box(2) = {x0, 0, 0, 1 - x0, 1, 1};
BooleanIntersection(3) = {Volume{1}; Delete;}{Volume{2}; Delete;};
Box(4) = {2 * x0, 0, -2, 2 - 2 * x0, 2, 2};
Point(100) = {0, 0, 0};
Field[1] = Distance;
Field[1].PointsList = {100};
Field[2] = Threshold; Field[2].InField = 1; Field[2].SizeMin = h; Field[2].SizeMax = H;
Field[2].DistMin = 0.15; Field[2].DistMax = 1.5;
Background Field = 2;
Mesh.MeshSizeExtendFromBoundary = 0;
Mesh.MeshSizeFromPoints = 0;
Mesh.MeshSizeFromCurvature = 0;
e = 1e-6;
Physical Surface("sphere_top") = Surface In BoundingBox{x0 - e, -e, 1 - e, 1 + e, 1 + e, 1 + e};
If (!half)
  Physical Surface("sphere_x0") = Surface In BoundingBox{-e, -e, -e, e, 1 + e, 1 + e};
  Physical Surface("block_x0") = Surface In BoundingBox{-e, -e, -2 - e, e, 2 + e, e};
EndIf
Physical Surface("sphere_y0") = Surface In BoundingBox{x0 - e, -e, -e, 1 + e, e, 1 + e};
Physical Surface("block_top") = Surface In BoundingBox{2 * x0 - e, -e, -e, 2 + e, 2 + e, e};
Physical Surface("block_y0") = Surface In BoundingBox{2 * x0 - e, -e, -2 - e, 2 + e, e, e};
Physical Surface("block_bottom") = Surface In BoundingBox{2 * x0 - e, -e, -2 - e, 2 + e, 2 + e, -2 + e};
bnd[] = Abs(Boundary{Volume{3};});
curved[] = {};
For i In {0:#bnd[] - 1}
  bb[] = BoundingBox Surface{bnd[i]};
  If (bb[3] - bb[0] > 0.5 && bb[4] - bb[1] > 0.5 && bb[5] - bb[2] > 0.5)
    curved[] += {bnd[i]};
  EndIf
EndFor
Physical Surface("sphere_surface") = {curved[]};
Physical Volume("sphere") = {3};
Physical Volume("block") = {4};
