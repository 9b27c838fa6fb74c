/* The peer of htfeti's poisson2d for bench/petsc_poisson.py: -Laplace u = 1 on (0,1)^2, u = 0 on
   the boundary, bilinear (Q1) elements on an n x n grid, the load at each element's centroid
   times its area shared equally by its 4 nodes (htfeti's centroid rule), assembled by PETSc
   (DMDA) and solved by CG preconditioned with hypre's BoomerAMG to a relative residual
   ||b - A u|| <= rtol ||b|| (unpreconditioned norm). Prints one JSON line: sizes, iterations,
   seconds of assembly, preconditioner setup and solve, and the energy 1/2 u'Au - b'u (with the
   Dirichlet dofs eliminated it equals htfeti's objective).
   Usage: petsc_poisson -n 2000 [-rtol 1e-4] [PETSc options]  (run under mpiexec for ranks) */
#include <petscdmda.h>
#include <petscksp.h>

int main(int argc, char** argv) {
  PetscInt n = 64;
  PetscReal rtol = 1e-4;
  PetscCall(PetscInitialize(&argc, &argv, NULL, NULL));
  PetscCall(PetscOptionsGetInt(NULL, NULL, "-n", &n, NULL));
  PetscCall(PetscOptionsGetReal(NULL, NULL, "-rtol", &rtol, NULL));
  MPI_Comm comm = PETSC_COMM_WORLD;
  double t0 = MPI_Wtime();
  DM da;
  PetscCall(DMDACreate2d(comm, DM_BOUNDARY_NONE, DM_BOUNDARY_NONE, DMDA_STENCIL_BOX, n + 1, n + 1,
                         PETSC_DECIDE, PETSC_DECIDE, 1, 1, NULL, NULL, &da));
  PetscCall(DMSetFromOptions(da));
  PetscCall(DMSetUp(da));
  Mat A;
  Vec b, u;
  PetscCall(DMCreateMatrix(da, &A));
  PetscCall(DMCreateGlobalVector(da, &b));
  PetscCall(VecDuplicate(b, &u));
  /* Q1 Laplacian on a square (independent of its size in 2D), nodes counter-clockwise */
  const PetscScalar ke[4][4] = {{4. / 6, -1. / 6, -2. / 6, -1. / 6},
                                {-1. / 6, 4. / 6, -1. / 6, -2. / 6},
                                {-2. / 6, -1. / 6, 4. / 6, -1. / 6},
                                {-1. / 6, -2. / 6, -1. / 6, 4. / 6}};
  const PetscReal h = 1.0 / n, share = h * h / 4;
  PetscInt xs, ys, xm, ym;
  PetscCall(DMDAGetCorners(da, &xs, &ys, NULL, &xm, &ym, NULL));
  /* Each rank assembles the elements whose lower-left node it owns (the load into the ghosted
     local vector, added to the global one afterwards). */
  Vec bl;
  PetscScalar** bla;
  PetscCall(DMGetLocalVector(da, &bl));
  PetscCall(VecSet(bl, 0.0));
  PetscCall(DMDAVecGetArray(da, bl, &bla));
  for (PetscInt j = ys; j < ys + ym; ++j)
    for (PetscInt i = xs; i < xs + xm; ++i) {
      if (i >= n || j >= n) continue;
      MatStencil st[4] = {{0, j, i, 0}, {0, j, i + 1, 0}, {0, j + 1, i + 1, 0}, {0, j + 1, i, 0}};
      PetscCall(MatSetValuesStencil(A, 4, st, 4, st, &ke[0][0], ADD_VALUES));
      for (int a = 0; a < 4; ++a) bla[st[a].j][st[a].i] += share;
    }
  PetscCall(DMDAVecRestoreArray(da, bl, &bla));
  PetscCall(VecSet(b, 0.0));
  PetscCall(DMLocalToGlobal(da, bl, ADD_VALUES, b));
  PetscCall(DMRestoreLocalVector(da, &bl));
  PetscCall(MatAssemblyBegin(A, MAT_FINAL_ASSEMBLY));
  PetscCall(MatAssemblyEnd(A, MAT_FINAL_ASSEMBLY));
  /* Dirichlet u = 0 on the boundary: rows and columns replaced by the identity (symmetric). */
  PetscInt nb = 0;
  MatStencil* bst;
  PetscCall(PetscMalloc1(2 * (xm + ym) + 4, &bst));
  for (PetscInt j = ys; j < ys + ym; ++j)
    for (PetscInt i = xs; i < xs + xm; ++i)
      if (i == 0 || j == 0 || i == n || j == n) {
        bst[nb].i = i, bst[nb].j = j, bst[nb].k = 0, bst[nb].c = 0;
        ++nb;
      }
  PetscCall(MatZeroRowsColumnsStencil(A, nb, bst, 1.0, NULL, NULL));
  PetscScalar** ba;
  PetscCall(DMDAVecGetArray(da, b, &ba));
  for (PetscInt k = 0; k < nb; ++k) ba[bst[k].j][bst[k].i] = 0.0;
  PetscCall(DMDAVecRestoreArray(da, b, &ba));
  PetscCall(PetscFree(bst));
  const double t_assembly = MPI_Wtime() - t0;

  KSP ksp;
  PC pc;
  PetscCall(KSPCreate(comm, &ksp));
  PetscCall(KSPSetOperators(ksp, A, A));
  PetscCall(KSPSetType(ksp, KSPCG));
  PetscCall(KSPGetPC(ksp, &pc));
  PetscCall(PCSetType(pc, PCHYPRE));
  PetscCall(PCHYPRESetType(pc, "boomeramg"));
  PetscCall(KSPSetNormType(ksp, KSP_NORM_UNPRECONDITIONED));
  PetscCall(KSPSetTolerances(ksp, rtol, 0.0, PETSC_DEFAULT, 10000));
  PetscCall(KSPSetFromOptions(ksp));
  t0 = MPI_Wtime();
  PetscCall(KSPSetUp(ksp));
  PetscCall(PCSetUp(pc));
  const double t_setup = MPI_Wtime() - t0;
  t0 = MPI_Wtime();
  PetscCall(KSPSolve(ksp, b, u));
  const double t_solve = MPI_Wtime() - t0;
  PetscInt its;
  KSPConvergedReason reason;
  PetscCall(KSPGetIterationNumber(ksp, &its));
  PetscCall(KSPGetConvergedReason(ksp, &reason));
  Vec Au;
  PetscCall(VecDuplicate(u, &Au));
  PetscCall(MatMult(A, u, Au));
  PetscScalar uAu, bu;
  PetscCall(VecDot(u, Au, &uAu));
  PetscCall(VecDot(b, u, &bu));
  PetscCall(VecAYPX(Au, -1.0, b)); /* b - A u */
  PetscReal rn, bn;
  PetscCall(VecNorm(Au, NORM_2, &rn));
  PetscCall(VecNorm(b, NORM_2, &bn));
  int size;
  MPI_Comm_size(comm, &size);
  PetscCall(PetscPrintf(comm,
                        "{\"n\": %d, \"unknowns\": %lld, \"ranks\": %d, \"iterations\": %d, "
                        "\"converged\": %s, \"relative_residual\": %.6e, \"assembly_s\": %.4f, "
                        "\"pc_setup_s\": %.4f, \"solve_s\": %.4f, \"total_s\": %.4f, "
                        "\"objective\": %.15e}\n",
                        (int)n, (long long)(n + 1) * (n + 1), size, (int)its,
                        reason > 0 ? "true" : "false", (double)(rn / bn), t_assembly, t_setup,
                        t_solve, t_assembly + t_setup + t_solve, (double)(0.5 * uAu - bu)));
  PetscCall(VecDestroy(&Au));
  PetscCall(KSPDestroy(&ksp));
  PetscCall(VecDestroy(&u));
  PetscCall(VecDestroy(&b));
  PetscCall(MatDestroy(&A));
  PetscCall(DMDestroy(&da));
  PetscCall(PetscFinalize());
  return 0;
}
