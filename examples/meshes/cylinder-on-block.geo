// Hertz contact in plane strain, half model (x >= 0, symmetric about x = 0): the lower quarter of
// a cylinder of radius R = 1 (its flat top at y = 1, where the load acts) touching at the origin
// the block [0, 4] x [-4, 0]; with full = 1 the whole model (the lower half of the cylinder on
// [-4, 4] x [-4, 0], for tangential loads). The two bodies are meshed apart (no shared nodes),
// finest near the contact point (size h), coarsest (size H) far from it; quad4 (quad = 1,
// default) or tri3. Physical groups: "cylinder", "block" (surfaces), "cylinder_arc" (the contact
// surface), "cylinder_top", "block_top" (y = 0), "block_bottom" (y = -4), and in the half model
// "cylinder_axis" and "block_axis" (x = 0).
// Regenerate: gmsh -2 -format msh41 cylinder-on-block.geo -o cylinder-on-block.msh
//             (coarser or finer: -setnumber h 0.02)
SetFactory("OpenCASCADE");
If (!Exists(h)) h = 0.005; EndIf
If (!Exists(H)) H = 0.25; EndIf
If (!Exists(quad)) quad = 1; EndIf
If (!Exists(full)) full = 0; EndIf
x0 = full ? -1 : 0;
Disk(1) = {0, 1, 0, 1};
Rectangle(2) = {x0, 0, 0, 1 - x0, 1};
BooleanIntersection(3) = {Surface{1}; Delete;}{Surface{2}; Delete;};
Rectangle(4) = {4 * x0, -4, 0, 4 - 4 * x0, 4};
// Size: h within 0.1 of the contact point, growing linearly to H at distance 1.5.
Point(100) = {0, 0, 0};
Field[1] = Distance;
Field[1].PointsList = {100};
Field[2] = Threshold; Field[2].InField = 1; Field[2].SizeMin = h; Field[2].SizeMax = H;
Field[2].DistMin = 0.1; Field[2].DistMax = 1.5;
Background Field = 2;
Mesh.MeshSizeExtendFromBoundary = 0;
Mesh.MeshSizeFromPoints = 0;
Mesh.MeshSizeFromCurvature = 0;
If (quad)
  Mesh.RecombineAll = 1;
  Mesh.Algorithm = 6;
EndIf
e = 1e-6;
Physical Curve("cylinder_top") = Curve In BoundingBox{x0 - e, 1 - e, -e, 1 + e, 1 + e, e};
If (!full)
  Physical Curve("cylinder_axis") = Curve In BoundingBox{-e, -e, -e, e, 1 + e, e};
  Physical Curve("block_axis") = Curve In BoundingBox{-e, -4 - e, -e, e, e, e};
EndIf
Physical Curve("block_top") = Curve In BoundingBox{4 * x0 - e, -e, -e, 4 + e, e, e};
Physical Curve("block_bottom") = Curve In BoundingBox{4 * x0 - e, -4 - e, -e, 4 + e, -4 + e, e};
bnd[] = Abs(Boundary{Surface{3};});
arc[] = {};
For i In {0:#bnd[] - 1}
  bb[] = BoundingBox Curve{bnd[i]};
  If (bb[3] - bb[0] > 0.5 && bb[4] - bb[1] > 0.5)
    arc[] += {bnd[i]};
  EndIf
EndFor
Physical Curve("cylinder_arc") = {arc[]};
Physical Surface("cylinder") = {3};
Physical Surface("block") = {4};
