// Two unit squares stacked along y and meshed apart (no shared nodes: the OpenCASCADE kernel
// without fragments): the lower one with n1 x n1 elements, the upper one with n2 x m2; quad4
// (quad = 1) or tri3 (quad = 0). The contact patch test of tests/test_multibody.cpp.
SetFactory("OpenCASCADE");
If (!Exists(quad)) quad = 1; EndIf
If (!Exists(n1)) n1 = 5; EndIf
If (!Exists(n2)) n2 = 7; EndIf
If (!Exists(m2)) m2 = 4; EndIf
Rectangle(1) = {0, 0, 0, 1, 1};
Rectangle(2) = {0, 1, 0, 1, 1};
Macro Divide
  cs[] = Abs(Boundary{Surface{surf};});
  For i In {0:#cs[] - 1}
    bb[] = BoundingBox Curve{cs[i]};
    If (bb[3] - bb[0] > 0.5)
      Transfinite Curve{cs[i]} = nx + 1;
    Else
      Transfinite Curve{cs[i]} = ny + 1;
    EndIf
  EndFor
  Transfinite Surface{surf};
  If (quad)
    Recombine Surface{surf};
  EndIf
Return
surf = 1; nx = n1; ny = n1; Call Divide;
surf = 2; nx = n2; ny = m2; Call Divide;
e = 1e-6;
Physical Curve("bottom") = Curve In BoundingBox{-e, -e, -e, 1 + e, e, e};
Physical Curve("lower_x0") = Curve In BoundingBox{-e, -e, -e, e, 1 + e, e};
Physical Curve("upper_x0") = Curve In BoundingBox{-e, 1 - e, -e, e, 2 + e, e};
Physical Curve("top") = Curve In BoundingBox{-e, 2 - e, -e, 1 + e, 2 + e, e};
// The two curves at y = 1 (OpenCASCADE numbers a rectangle's sides bottom, right, top, left).
Physical Curve("lower_top") = {3};
Physical Curve("upper_bottom") = {5};
Physical Surface("lower") = {1};
Physical Surface("upper") = {2};
