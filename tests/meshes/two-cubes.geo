// Two unit cubes stacked along z and meshed apart (no shared nodes: OpenCASCADE boxes without
// fragments): the lower one with n1 x n1 x n1 elements, the upper one with n2 x m2 x m2; hex8
// (hex = 1) or tet4 (hex = 0).
SetFactory("OpenCASCADE");
If (!Exists(hex)) hex = 1; EndIf
If (!Exists(n1)) n1 = 4; EndIf
If (!Exists(n2)) n2 = 5; EndIf
If (!Exists(m2)) m2 = 3; EndIf
Box(1) = {0, 0, 0, 1, 1, 1};
Box(2) = {0, 0, 1, 1, 1, 1};
Macro Divide
  cs[] = Unique(Abs(Boundary{Surface{Abs(Boundary{Volume{vol};})};}));
  For i In {0:#cs[] - 1}
    bb[] = BoundingBox Curve{cs[i]};
    If (bb[3] - bb[0] > 0.5)
      Transfinite Curve{cs[i]} = nx + 1;
    EndIf
    If (bb[4] - bb[1] > 0.5)
      Transfinite Curve{cs[i]} = ny + 1;
    EndIf
    If (bb[5] - bb[2] > 0.5)
      Transfinite Curve{cs[i]} = nz + 1;
    EndIf
  EndFor
  Transfinite Surface{Abs(Boundary{Volume{vol};})};
  If (hex)
    Recombine Surface{Abs(Boundary{Volume{vol};})};
    Transfinite Volume{vol};
  EndIf
Return
vol = 1; nx = n1; ny = n1; nz = n1; Call Divide;
vol = 2; nx = n2; ny = m2; nz = m2; Call Divide;
If (hex)
  Mesh.Recombine3DAll = 1;
EndIf
// OpenCASCADE's box faces: x = 0, x = 1, y = 0, y = 1, z = 0, z = 1.
Physical Surface("bottom") = {5};
Physical Surface("lower_top") = {6};
Physical Surface("lower_x0") = {1};
Physical Surface("lower_y0") = {3};
Physical Surface("upper_bottom") = {11};
Physical Surface("top") = {12};
Physical Surface("upper_x0") = {7};
Physical Surface("upper_y0") = {9};
Physical Volume("lower") = {1};
Physical Volume("upper") = {2};
