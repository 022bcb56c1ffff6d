"""Independent static solutions of SOFA's liver demo (server/scenes/sofa-liver.toml).

Solved with scikit-fem (P1 tetrahedra, its own assembly and quadrature) and SciPy
(sparse direct solves, Newton-Krylov), sharing no code with laparo:

* linear elasticity: scikit-fem's own `linear_elasticity` bilinear form, one sparse
  direct solve;
* corotational ("corotated linear") elasticity, the model of laparo's
  `[material] model = "corotational"`: energy density
  Psi(F) = mu |S - I|^2 + lambda/2 (tr(S - I))^2 with F = R S the polar decomposition,
  first Piola stress P = R (lambda tr(S - I) I + 2 mu (S - I)); the rotation comes from
  LAPACK's SVD (F = U diag(s) V^T, R = U V^T with the sign of the last column of U
  flipped when det F < 0), not from laparo's iteration; the nonlinear equilibrium
  int P : grad v = int rho g . v is solved by Newton-Krylov from the linear answer,
  to a residual below 1e-13 of the load.

Units are SOFA's (the mesh unread, unscaled): E = 3000, nu = 0.3, rho = 1,
g = (0, -9.81, 0), nodes 3, 39 and 64 (0-based, file order) fixed.

Regenerate (any Python 3 with pip):
    python3 -m venv /tmp/venv && /tmp/venv/bin/pip install scikit-fem==12.0.2
    /tmp/venv/bin/python server/benches/reference/sofa_liver_static.py \
        > server/benches/reference/sofa_liver_static.csv
"""

import os
import sys

import numpy as np
import scipy
import scipy.optimize
import skfem
from skfem import Basis, ElementTetP1, ElementVector, LinearForm, MeshTet, asm, condense, solve
from skfem.helpers import ddot, grad
from skfem.models.elasticity import lame_parameters, linear_elasticity

HERE = os.path.dirname(os.path.abspath(__file__))
MESH = os.path.join(HERE, "..", "..", "meshes", "liver.msh")
E, NU, RHO = 3000.0, 0.3, 1.0
GRAVITY = np.array([0.0, -9.81, 0.0])
FIXED = [3, 39, 64]


def read_msh_v1(path):
    """Nodes and tetrahedra of a Gmsh 1 file ($NOD / $ELM), 0-based, file order."""
    lines = open(path).read().split("\n")
    i = lines.index("$NOD")
    n = int(lines[i + 1])
    ids, pts = {}, []
    for k in range(n):
        f = lines[i + 2 + k].split()
        ids[int(f[0])] = k
        pts.append([float(v) for v in f[1:4]])
    i = lines.index("$ELM")
    m = int(lines[i + 1])
    tets = []
    for k in range(m):
        f = [int(v) for v in lines[i + 2 + k].split()]
        if f[1] == 4:
            tets.append([ids[v] for v in f[5:9]])
    p, t = np.array(pts).T, np.array(tets).T
    # Positive orientation, as laparo's reader leaves it.
    d = np.einsum("ijk->kij", np.stack([p[:, t[1]] - p[:, t[0]], p[:, t[2]] - p[:, t[0]], p[:, t[3]] - p[:, t[0]]], axis=1))
    neg = np.linalg.det(d) < 0
    t[1, neg], t[2, neg] = t[2, neg].copy(), t[1, neg].copy()
    return p, t


def polar_rotation(F):
    """R of F = R S for F of shape (3, 3, ...), by SVD; det R = +1."""
    Fm = np.moveaxis(F, (0, 1), (-2, -1))
    U, _, Vt = np.linalg.svd(Fm)
    flip = np.linalg.det(U @ Vt) < 0
    U[flip, :, 2] *= -1
    return np.moveaxis(U @ Vt, (-2, -1), (0, 1))


def main():
    p, t = read_msh_v1(MESH)
    mesh = MeshTet(p, t)
    basis = Basis(mesh, ElementVector(ElementTetP1()), intorder=2)
    lam, mu = lame_parameters(E, NU)
    K = asm(linear_elasticity(lam, mu), basis)

    @LinearForm
    def weight(v, w):
        return RHO * (GRAVITY[0] * v[0] + GRAVITY[1] * v[1] + GRAVITY[2] * v[2])

    f = asm(weight, basis)
    fixed = basis.nodal_dofs[:, FIXED].ravel()
    u_lin = solve(*condense(K, f, D=fixed))

    eye = np.eye(3).reshape(3, 3, 1, 1)

    @LinearForm
    def internal(v, w):
        F = grad(w["u"]) + eye
        R = polar_rotation(F)
        S = np.einsum("jixy,jkxy->ikxy", R, F)
        eps = 0.5 * (S + np.einsum("ijxy->jixy", S)) - eye
        sigma = lam * np.einsum("iixy->xy", eps) * eye + 2.0 * mu * eps
        P = np.einsum("ijxy,jkxy->ikxy", R, sigma)
        return ddot(P, grad(v))

    free = np.setdiff1d(np.arange(basis.N), fixed)

    def residual(x):
        u = np.zeros(basis.N)
        u[free] = x
        r = asm(internal, basis, u=basis.interpolate(u)) - f
        return r[free]

    scale = np.linalg.norm(f[free])
    x = scipy.optimize.newton_krylov(
        residual, u_lin[free], f_tol=1e-13 * scale, method="lgmres", maxiter=200
    )
    u_cor = np.zeros(basis.N)
    u_cor[free] = x
    res = np.linalg.norm(residual(x)) / scale

    U_lin = u_lin[basis.nodal_dofs].T
    U_cor = u_cor[basis.nodal_dofs].T
    print("# SOFA liver demo, static equilibrium, displacement of every node (SOFA units).")
    print(f"# scikit-fem {skfem.__version__}, numpy {np.__version__}, scipy {scipy.__version__}")
    print(f"# corotational relative residual {res:.2e}; largest displacement linear "
          f"{np.linalg.norm(U_lin, axis=1).max():.6f}, corotational {np.linalg.norm(U_cor, axis=1).max():.6f}")
    print("# regenerate: see server/benches/reference/sofa_liver_static.py")
    print("node,linear_x,linear_y,linear_z,corotational_x,corotational_y,corotational_z")
    for i in range(U_lin.shape[0]):
        a, b = U_lin[i], U_cor[i]
        print(f"{i},{a[0]:.15e},{a[1]:.15e},{a[2]:.15e},{b[0]:.15e},{b[1]:.15e},{b[2]:.15e}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
