
static double dot_n(const double *x, const double *y)
{
    double s = 0.0;
    for (int i = 0; i < N; ++i) s += x[i] * y[i];
    return s;
}

/* the blocks M, h - Q, J, c as the dense route has them (the NumPy fallback and the Python API):
   column j of M is tree_residual at a = e_j without bias, h - Q at a = 0 */
void appell_blocks(double t, const double *restrict q, const double *restrict w, const double *restrict a,
                   const double *restrict p, double *restrict M, double *restrict hQ, double *restrict J,
                   double *restrict c)
{
    double U[TD * NB], cb[TD * NB], m[NB], tau[N], e[N], col[N], zero[TD * NB > N ? TD * NB : N] = {0.0};
    appell_tree_terms(t, q, w, a, p, U, cb, m, tau, J, c);
    for (int i = 0; i < N; ++i) e[i] = 0.0;
    for (int j = 0; j < N; ++j) {
        e[j] = 1.0;
        tree_residual(U, zero, m, zero, e, col);
        for (int i = 0; i < N; ++i) M[i * N + j] = col[i];
        e[j] = 0.0;
    }
    tree_residual(U, cb, m, tau, e, hQ);
}

/* (1.4) by the tree: a = a_0 + Y x with M a_0 = Q - h, Y = M^{-1} J^T (O(NB) per column) and
   (J Y) x = -(J a_0 + c), the solution of the reduced equations; then each reaction by (1.5)
   from E = M a + h - Q. 0: solved; 1: partition unusable; 2: singular or not finite */
int appell_solve(double t, const double *q, const double *w, const double *p, const double *bias,
                 const int *dep, double cond_max, double *a, double *lam, double *R)
{
    double U[TD * NB], cb[TD * NB], m[NB], rhs[(S + 1) * N], x[(S + 1) * N], D[DIM(S)], Jh[DIM(S * S)], E[N];
    double *J = rhs + N, c[DIM(S)];
    int piv[DIM(S)];
    appell_tree_terms(t, q, w, 0, p, U, cb, m, rhs, J, c);
    if (bias) for (int r = 0; r < S; ++r) c[r] += bias[r];
    double kappa;
    if (S > 0 && scaled_block(J, dep, cond_max, D, Jh, piv, &kappa)) return 1;
    if (tree_solve(U, cb, m, rhs, x)) return 2;         /* a_0 and the columns of Y = M^{-1} J^T */
    for (int i = 0; i < N; ++i) a[i] = x[i];
    if (S > 0) {
        const double *Y = x + N;
        double G[DIM(S * S)], z[DIM(S)];
        int pg[DIM(S)];
        for (int r = 0; r < S; ++r) {
            z[r] = -(c[r] + dot_n(J + r * N, a));
            for (int k = 0; k < S; ++k) G[r * S + k] = dot_n(J + r * N, Y + k * N);
        }
        if (lu_factor(S, G, pg)) return 2;
        lu_solve(S, G, pg, z);
        for (int r = 0; r < S; ++r) for (int i = 0; i < N; ++i) a[i] += Y[r * N + i] * z[r];
    }
    tree_residual(U, cb, m, rhs, a, E);
    multipliers(E, dep, D, Jh, piv, lam);
    return finish(J, a, lam, R);
}
