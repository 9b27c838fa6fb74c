// The block [0, 1] x [0, 1] x [-1, 0] of graded_block_hex.geo meshed with tet4 graded toward the
// origin by a size field: size h within 0.1 of it, H beyond 1, well-shaped cells throughout (the
// grading of an unstructured mesher). bench/graded_hertz.py:
// gmsh -3 -setnumber h 0.004 -setnumber H 0.07 -format msh41 graded_block_tet.geo -o F.msh
SetFactory("OpenCASCADE");
If (!Exists(h)) h = 0.01; EndIf
If (!Exists(H)) H = 0.15; EndIf
Box(1) = {0, 0, -1, 1, 1, 1};
Point(100) = {0, 0, 0};
Field[1] = Distance; Field[1].PointsList = {100};
Field[2] = Threshold; Field[2].InField = 1; Field[2].SizeMin = h; Field[2].SizeMax = H;
Field[2].DistMin = 0.1; Field[2].DistMax = 1.0;
Background Field = 2;
Mesh.MeshSizeExtendFromBoundary = 0; Mesh.MeshSizeFromPoints = 0; Mesh.MeshSizeFromCurvature = 0;
e = 1e-6;
Physical Surface("top") = Surface In BoundingBox{-e, -e, -e, 1 + e, 1 + e, e};
Physical Surface("bottom") = Surface In BoundingBox{-e, -e, -1 - e, 1 + e, 1 + e, -1 + e};
Physical Surface("x0") = Surface In BoundingBox{-e, -e, -1 - e, e, 1 + e, e};
Physical Surface("y0") = Surface In BoundingBox{-e, -e, -1 - e, 1 + e, e, e};
Physical Volume("block") = {1};
