/* The peer of htfeti's cube-obstacle (docs: ../shared/DESIGN.md, examples/cube-obstacle.toml) for
   bench/cube_obstacle_peer.py: the same discrete problem, assembled and solved by PETSc.
     - the cube [0,100]^3, n x n x n hex8 elements (trilinear, 2x2x2 Gauss: exact for the
       stiffness of a cube), E = 2.1e7, nu = 0.3; own weight, density 7850, acceleration
       -9.8066 in z, each element's weight shared equally by its 8 nodes (htfeti's rule, which
       for a trilinear cube equals the consistent load);
     - clamped (u = 0) on x = 0: rows and columns replaced by the diagonal of K (symmetric);
     - the nodes of z = 0: u_z >= -A sin(pi x / 50) (the obstacle), as bounds of the variables.
   The bound-constrained QP min 1/2 u'Ku - f'u is solved as a variational inequality by SNES VI
   (reduced-space active-set Newton, SNESVINEWTONRSLS) with CG preconditioned by GAMG, whose
   near-null space is the six rigid body motions of the node coordinates restricted to the
   variables of each Newton step's reduced system (see ReducedGamg). Defaults:
   -snes_rtol rtol -ksp_rtol rtol (the QP's relative precision; -rtol sets both), any PETSc
   option overrides them. Prints one JSON line: sizes, Newton and CG iterations, seconds of
   assembly and solve, the energy 1/2 u'Ku - f'u (with the clamped dofs eliminated it equals
   htfeti's objective), the number of nodes in contact, the largest violation of the bounds, and
   the peak RSS (sum and largest over the ranks, getrusage).
   Usage: petsc_cube_obstacle -n 40 [-amp 1] [-rtol 1e-4] [PETSc options]  (under mpiexec) */
#include <petscdmda.h>
#include <petscsnes.h>
#include <sys/resource.h>

typedef struct {
  Mat K;
  Vec f;
} Ctx;

/* F(u) = K u - f, the gradient of the energy. */
static PetscErrorCode residual(SNES snes, Vec u, Vec r, void* p) {
  (void)snes;
  Ctx* c = (Ctx*)p;
  PetscCall(MatMult(c->K, u, r));
  PetscCall(VecAXPY(r, -1.0, c->f));
  return 0;
}

/* The Jacobian is K, assembled once. */
static PetscErrorCode jacobian(SNES snes, Vec u, Mat J, Mat P, void* p) {
  (void)snes, (void)u, (void)J, (void)P, (void)p;
  return 0;
}

/* GAMG on the reduced system of each Newton step. SNES VI (rsls) solves on the inactive
   variables only, with a submatrix of K that carries no near-null space, and PETSc 3.18's GAMG
   cannot be set up again on a system of another size. So the KSP's preconditioner is a shell
   that, on every set-up, restricts the six rigid body motions to the inactive variables
   (orthonormalized), hands them to the reduced matrix as its near-null space and builds a new
   GAMG on it (options prefix "peer_": -peer_pc_gamg_threshold 0.01 and the like). */
typedef struct {
  SNES snes;
  MatNullSpace rbm; /* the rigid body motions of the whole cube */
  PC gamg;
} ReducedGamg;

static PetscErrorCode reduced_gamg_setup(PC pc) {
  ReducedGamg* g;
  Mat A, P;
  IS inactive;
  PetscBool has_const;
  PetscInt nv;
  const Vec* rbm;
  Vec sub[6];
  MatNullSpace nsp;
  PetscCall(PCShellGetContext(pc, &g));
  PetscCall(PCGetOperators(pc, &A, &P));
  PetscCall(SNESVIGetInactiveSet(g->snes, &inactive));
  PetscCall(MatNullSpaceGetVecs(g->rbm, &has_const, &nv, &rbm));
  for (PetscInt i = 0; i < nv; ++i) {
    Vec part;
    PetscCall(MatCreateVecs(P, &sub[i], NULL));
    PetscCall(VecGetSubVector(rbm[i], inactive, &part));
    PetscCall(VecCopy(part, sub[i]));
    PetscCall(VecRestoreSubVector(rbm[i], inactive, &part));
    for (int pass = 0; pass < 2; ++pass) /* Gram-Schmidt, twice */
      for (PetscInt j = 0; j < i; ++j) {
        PetscScalar d;
        PetscCall(VecDot(sub[i], sub[j], &d));
        PetscCall(VecAXPY(sub[i], -d, sub[j]));
      }
    PetscCall(VecNormalize(sub[i], NULL));
  }
  PetscCall(MatNullSpaceCreate(PetscObjectComm((PetscObject)pc), PETSC_FALSE, nv, sub, &nsp));
  PetscCall(MatSetNearNullSpace(P, nsp));
  PetscCall(MatNullSpaceDestroy(&nsp));
  for (PetscInt i = 0; i < nv; ++i) PetscCall(VecDestroy(&sub[i]));
  PetscCall(PCDestroy(&g->gamg));
  PetscCall(PCCreate(PetscObjectComm((PetscObject)pc), &g->gamg));
  PetscCall(PCSetType(g->gamg, PCGAMG));
  PetscCall(PCSetOptionsPrefix(g->gamg, "peer_"));
  PetscCall(PCSetOperators(g->gamg, A, P));
  PetscCall(PCSetFromOptions(g->gamg));
  PetscCall(PCSetUp(g->gamg));
  return 0;
}

static PetscErrorCode reduced_gamg_apply(PC pc, Vec x, Vec y) {
  ReducedGamg* g;
  PetscCall(PCShellGetContext(pc, &g));
  PetscCall(PCApply(g->gamg, x, y));
  return 0;
}

/* The stiffness matrix of a cube of side h (trilinear, 2x2x2 Gauss), nodes in the order
   (0,0,0) (1,0,0) (1,1,0) (0,1,0) (0,0,1) (1,0,1) (1,1,1) (0,1,1), dofs node-major. */
static void cube_stiffness(double h, double E, double nu, double ke[24][24]) {
  const int xi[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                        {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
  const double lam = E * nu / ((1 + nu) * (1 - 2 * nu)), mu = E / (2 * (1 + nu));
  const double g = 0.5 / sqrt(3.0);
  for (int a = 0; a < 24; ++a)
    for (int b = 0; b < 24; ++b) ke[a][b] = 0;
  for (int q = 0; q < 8; ++q) {
    const double x[3] = {0.5 + (xi[q][0] ? g : -g), 0.5 + (xi[q][1] ? g : -g),
                         0.5 + (xi[q][2] ? g : -g)};
    double dn[8][3]; /* dN_a/dx at the Gauss point (reference cube [0,1]^3 scaled by h) */
    for (int a = 0; a < 8; ++a)
      for (int d = 0; d < 3; ++d) {
        double v = 1;
        for (int e = 0; e < 3; ++e) {
          const double s = xi[a][e] ? x[e] : 1 - x[e];
          v *= e == d ? (xi[a][e] ? 1.0 : -1.0) / h : s;
        }
        dn[a][d] = v;
      }
    const double w = h * h * h / 8;
    for (int a = 0; a < 8; ++a)
      for (int b = 0; b < 8; ++b)
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j) {
            /* (B_a^T D B_b)_ij = lam d_i N_a d_j N_b + mu d_j N_a d_i N_b + mu delta_ij grad.grad */
            double v = lam * dn[a][i] * dn[b][j] + mu * dn[a][j] * dn[b][i];
            if (i == j) v += mu * (dn[a][0] * dn[b][0] + dn[a][1] * dn[b][1] + dn[a][2] * dn[b][2]);
            ke[3 * a + i][3 * b + j] += w * v;
          }
  }
}

int main(int argc, char** argv) {
  PetscInt n = 20;
  PetscReal amp = 1, rtol = 1e-4;
  PetscCall(PetscInitialize(&argc, &argv, NULL, NULL));
  PetscCall(PetscOptionsGetInt(NULL, NULL, "-n", &n, NULL));
  PetscCall(PetscOptionsGetReal(NULL, NULL, "-amp", &amp, NULL));
  PetscCall(PetscOptionsGetReal(NULL, NULL, "-rtol", &rtol, NULL));
  MPI_Comm comm = PETSC_COMM_WORLD;
  const double L = 100, E = 2.1e7, nu = 0.3, rho = 7850, gz = -9.8066, h = L / n;
  PetscCall(PetscBarrier(NULL));
  double t0 = MPI_Wtime();
  DM da;
  PetscCall(DMDACreate3d(comm, DM_BOUNDARY_NONE, DM_BOUNDARY_NONE, DM_BOUNDARY_NONE,
                         DMDA_STENCIL_BOX, n + 1, n + 1, n + 1, PETSC_DECIDE, PETSC_DECIDE,
                         PETSC_DECIDE, 3, 1, NULL, NULL, NULL, &da));
  PetscCall(DMSetFromOptions(da));
  PetscCall(DMSetUp(da));
  PetscCall(DMDASetUniformCoordinates(da, 0, L, 0, L, 0, L));
  Ctx c;
  Vec u, xl, xu, r;
  PetscCall(DMCreateMatrix(da, &c.K));
  PetscCall(DMCreateGlobalVector(da, &c.f));
  PetscCall(VecDuplicate(c.f, &u));
  PetscCall(VecDuplicate(c.f, &xl));
  PetscCall(VecDuplicate(c.f, &xu));
  PetscCall(VecDuplicate(c.f, &r));
  static double ke[24][24];
  cube_stiffness(h, E, nu, ke);
  const PetscInt off[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                              {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
  PetscInt xs, ys, zs, xm, ym, zm;
  PetscCall(DMDAGetCorners(da, &xs, &ys, &zs, &xm, &ym, &zm));
  /* Each rank assembles the elements whose lowest node it owns. */
  for (PetscInt k = zs; k < PetscMin(zs + zm, n); ++k)
    for (PetscInt j = ys; j < PetscMin(ys + ym, n); ++j)
      for (PetscInt i = xs; i < PetscMin(xs + xm, n); ++i) {
        MatStencil st[8];
        for (int a = 0; a < 8; ++a) {
          st[a].i = i + off[a][0], st[a].j = j + off[a][1], st[a].k = k + off[a][2];
          st[a].c = 0;
        }
        PetscCall(MatSetValuesBlockedStencil(c.K, 8, st, 8, st, &ke[0][0], ADD_VALUES));
      }
  PetscCall(MatAssemblyBegin(c.K, MAT_FINAL_ASSEMBLY));
  PetscCall(MatAssemblyEnd(c.K, MAT_FINAL_ASSEMBLY));
  /* The load (a node's share of the weight of its 1, 2, 4 or 8 elements) and the bounds. */
  PetscScalar ****fa, ****la, ****ua;
  PetscCall(DMDAVecGetArrayDOF(da, c.f, &fa));
  PetscCall(DMDAVecGetArrayDOF(da, xl, &la));
  PetscCall(DMDAVecGetArrayDOF(da, xu, &ua));
  PetscInt nclamped = 0;
  for (PetscInt k = zs; k < zs + zm; ++k)
    for (PetscInt j = ys; j < ys + ym; ++j)
      for (PetscInt i = xs; i < xs + xm; ++i) {
        const int elems = (i == 0 || i == n ? 1 : 2) * (j == 0 || j == n ? 1 : 2) *
                          (k == 0 || k == n ? 1 : 2);
        for (int d = 0; d < 3; ++d) {
          fa[k][j][i][d] = 0;
          la[k][j][i][d] = PETSC_NINFINITY;
          ua[k][j][i][d] = PETSC_INFINITY;
        }
        if (i == 0) {
          ++nclamped;
          continue;
        }
        fa[k][j][i][2] = rho * gz * h * h * h / 8 * elems;
        if (k == 0) la[k][j][i][2] = -amp * sin(PETSC_PI * (i * h) / 50);
      }
  PetscCall(DMDAVecRestoreArrayDOF(da, c.f, &fa));
  PetscCall(DMDAVecRestoreArrayDOF(da, xl, &la));
  PetscCall(DMDAVecRestoreArrayDOF(da, xu, &ua));
  /* Clamped: rows and columns of x = 0 replaced by K's diagonal (u = 0 there, f = 0 there). */
  MatStencil* cst;
  PetscCall(PetscMalloc1(3 * nclamped + 1, &cst));
  PetscInt nc = 0;
  for (PetscInt k = zs; k < zs + zm; ++k)
    for (PetscInt j = ys; j < ys + ym; ++j)
      if (xs == 0)
        for (int d = 0; d < 3; ++d) {
          cst[nc].i = 0, cst[nc].j = j, cst[nc].k = k, cst[nc].c = d;
          ++nc;
        }
  PetscCall(MatZeroRowsColumnsStencil(c.K, nc, cst, ke[0][0], NULL, NULL));
  PetscCall(PetscFree(cst));
  /* GAMG's near-null space: the six rigid body motions of the coordinates. */
  Vec coords;
  MatNullSpace rbm;
  PetscCall(DMGetCoordinates(da, &coords));
  PetscCall(MatNullSpaceCreateRigidBody(coords, &rbm));
  PetscCall(MatSetNearNullSpace(c.K, rbm));
  const double t_assembly = MPI_Wtime() - t0;

  SNES snes;
  KSP ksp;
  PC pc;
  PetscCall(SNESCreate(comm, &snes));
  PetscCall(SNESSetType(snes, SNESVINEWTONRSLS));
  PetscCall(SNESSetFunction(snes, r, residual, &c));
  PetscCall(SNESSetJacobian(snes, c.K, c.K, jacobian, &c));
  PetscCall(SNESVISetVariableBounds(snes, xl, xu));
  PetscCall(SNESSetTolerances(snes, 0.0, rtol, 0.0, 100, 100000));
  PetscCall(SNESGetKSP(snes, &ksp));
  PetscCall(KSPSetType(ksp, KSPCG));
  PetscCall(KSPSetTolerances(ksp, rtol, 0.0, PETSC_DEFAULT, 10000));
  PetscCall(KSPGetPC(ksp, &pc));
  ReducedGamg gamg = {snes, rbm, NULL};
  PetscCall(PCSetType(pc, PCSHELL));
  PetscCall(PCShellSetContext(pc, &gamg));
  PetscCall(PCShellSetSetUp(pc, reduced_gamg_setup));
  PetscCall(PCShellSetApply(pc, reduced_gamg_apply));
  PetscCall(PCShellSetName(pc, "GAMG on the inactive variables, rigid body modes restricted"));
  PetscCall(SNESSetFromOptions(snes));
  PetscCall(VecSet(u, 0.0));
  PetscCall(PetscBarrier(NULL));
  t0 = MPI_Wtime();
  PetscCall(SNESSolve(snes, NULL, u));
  const double t_solve = MPI_Wtime() - t0;
  PetscInt newton, cg;
  SNESConvergedReason reason;
  PetscCall(SNESGetIterationNumber(snes, &newton));
  PetscCall(SNESGetLinearSolveIterations(snes, &cg));
  PetscCall(SNESGetConvergedReason(snes, &reason));

  /* The energy, the contact nodes (u_z within 1e-8 h of the obstacle) and the violation. */
  Vec Ku;
  PetscCall(VecDuplicate(u, &Ku));
  PetscCall(MatMult(c.K, u, Ku));
  PetscScalar uKu, fu;
  PetscCall(VecDot(u, Ku, &uKu));
  PetscCall(VecDot(c.f, u, &fu));
  PetscScalar ****ux, ****lx;
  PetscCall(DMDAVecGetArrayDOFRead(da, u, &ux));
  PetscCall(DMDAVecGetArrayDOFRead(da, xl, &lx));
  long long active = 0;
  double violation = 0;
  if (zs == 0)
    for (PetscInt j = ys; j < ys + ym; ++j)
      for (PetscInt i = PetscMax(xs, 1); i < xs + xm; ++i) {
        const double gap = ux[0][j][i][2] - lx[0][j][i][2];
        if (gap < 1e-8 * h) ++active;
        if (-gap > violation) violation = -gap;
      }
  PetscCall(DMDAVecRestoreArrayDOFRead(da, u, &ux));
  PetscCall(DMDAVecRestoreArrayDOFRead(da, xl, &lx));
  long long active_sum;
  double violation_max;
  MPI_Allreduce(&active, &active_sum, 1, MPI_LONG_LONG, MPI_SUM, comm);
  MPI_Allreduce(&violation, &violation_max, 1, MPI_DOUBLE, MPI_MAX, comm);
  struct rusage ru;
  getrusage(RUSAGE_SELF, &ru);
  double rss = ru.ru_maxrss / 1024.0, rss_sum, rss_max; /* MB */
  MPI_Allreduce(&rss, &rss_sum, 1, MPI_DOUBLE, MPI_SUM, comm);
  MPI_Allreduce(&rss, &rss_max, 1, MPI_DOUBLE, MPI_MAX, comm);
  int size;
  MPI_Comm_size(comm, &size);
  PetscCall(PetscPrintf(
      comm,
      "{\"n\": %d, \"amplitude\": %.6e, \"unknowns\": %lld, \"ranks\": %d, \"rtol\": %.3e, "
      "\"newton_iterations\": %d, \"cg_iterations\": %d, \"converged\": %s, \"reason\": %d, "
      "\"assembly_s\": %.4f, \"solve_s\": %.4f, \"total_s\": %.4f, \"objective\": %.15e, "
      "\"contact_nodes\": %lld, \"max_violation\": %.3e, \"peak_rss_mb_sum\": %.1f, "
      "\"peak_rss_mb_max_rank\": %.1f}\n",
      (int)n, (double)amp, 3LL * (n + 1) * (n + 1) * (n + 1), size, (double)rtol, (int)newton,
      (int)cg, reason > 0 ? "true" : "false", (int)reason, t_assembly, t_solve,
      t_assembly + t_solve, (double)(0.5 * uKu - fu), active_sum, violation_max, rss_sum, rss_max));
  PetscCall(VecDestroy(&Ku));
  PetscCall(SNESDestroy(&snes));
  PetscCall(PCDestroy(&gamg.gamg));
  PetscCall(MatNullSpaceDestroy(&rbm));
  PetscCall(VecDestroy(&u));
  PetscCall(VecDestroy(&xl));
  PetscCall(VecDestroy(&xu));
  PetscCall(VecDestroy(&r));
  PetscCall(VecDestroy(&c.f));
  PetscCall(MatDestroy(&c.K));
  PetscCall(DMDestroy(&da));
  PetscCall(PetscFinalize());
  return 0;
}
