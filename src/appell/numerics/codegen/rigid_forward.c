
/* M = L^T D L over the tree's speeds (Featherstone 2008, section 6.5), in place on H (N x N, the
   speeds in SPEEDS order, where speed e's ancestors CHAIN[CHAIN_AT[e]], ... come before it and
   M's entries vanish between speeds on different branches): D on the diagonal, L below it.
   O(sum of squared depths) instead of N^3 / 3. 1 where M is not positive definite. */
static int ltdl(double *H)
{
    for (int k = N - 1; k >= 0; --k) {
        const double d = H[k * N + k];
        if (!(d > 0.0) || !isfinite(d)) return 1;
        for (int u = CHAIN_AT[k]; u < CHAIN_AT[k + 1]; ++u) {
            const int i = CHAIN[u];
            const double x = H[k * N + i] / d;
            H[i * N + i] -= x * H[k * N + i];
            for (int v = u + 1; v < CHAIN_AT[k + 1]; ++v) H[i * N + CHAIN[v]] -= x * H[k * N + CHAIN[v]];
            H[k * N + i] = x;
        }
    }
    return 0;
}

/* B <- M^{-1} B for the K columns of B (column r at B + r N, SPEEDS order) with the factors of
   ltdl */
static void ltdl_solve(const double *H, int K, double *B)
{
    for (int i = N - 1; i >= 0; --i)
        for (int u = CHAIN_AT[i]; u < CHAIN_AT[i + 1]; ++u) {
            const double h = H[i * N + CHAIN[u]];
            for (int r = 0; r < K; ++r) B[r * N + CHAIN[u]] -= h * B[r * N + i];
        }
    for (int i = 0; i < N; ++i)
        for (int r = 0; r < K; ++r) B[r * N + i] /= H[i * N + i];
    for (int i = 0; i < N; ++i)
        for (int u = CHAIN_AT[i]; u < CHAIN_AT[i + 1]; ++u) {
            const double h = H[i * N + CHAIN[u]];
            for (int r = 0; r < K; ++r) B[r * N + i] -= h * B[r * N + CHAIN[u]];
        }
}

/* (1.4) on the tree's factors: a = a_0 + Y z with M a_0 = Q - h, Y = M^{-1} J^T and
   (J Y) z = -(J a_0 + c) (the accelerations of the split), then each reaction by (1.5) from
   E = M a + h - Q with the partition DEP0. 1 where this does not apply (M not positive
   definite, the partition unusable or so ill-conditioned that the split refines its result):
   the caller takes the dense split. */
static int rigid_solve(const double *M, const double *hQ, const double *J, const double *c, double *a, double *lam)
{
    double H[N * N], x[(S + 1) * N], D[DIM(S)], Jh[DIM(S * S)], kappa = 1.0;
    int piv[DIM(S)];
    if (S > 0 && (scaled_block(J, DEP0, KEEP_CONDITION, D, Jh, piv, &kappa) || kappa >= REFINE_CONDITION)) return 1;
    for (int e = 0; e < N; ++e)
        for (int f = 0; f <= e; ++f) H[e * N + f] = M[SPEEDS[e] * N + SPEEDS[f]];
    if (ltdl(H)) return 1;
    for (int e = 0; e < N; ++e) {
        x[e] = -hQ[SPEEDS[e]];
        for (int r = 0; r < S; ++r) x[(r + 1) * N + e] = J[r * N + SPEEDS[e]];
    }
    ltdl_solve(H, S + 1, x);
    if (S > 0) {
        double G[DIM(S * S)], z[DIM(S)];
        int pg[DIM(S)];
        for (int r = 0; r < S; ++r) {
            double s = c[r];
            for (int e = 0; e < N; ++e) s += J[r * N + SPEEDS[e]] * x[e];
            z[r] = -s;
            for (int k = 0; k < S; ++k) {
                double g = 0.0;
                for (int e = 0; e < N; ++e) g += J[r * N + SPEEDS[e]] * x[(k + 1) * N + e];
                G[r * S + k] = g;
            }
        }
        if (lu_factor(S, G, pg)) return 1;
        lu_solve(S, G, pg, z);
        for (int k = 0; k < S; ++k) for (int e = 0; e < N; ++e) x[e] += x[(k + 1) * N + e] * z[k];
    }
    for (int e = 0; e < N; ++e) a[SPEEDS[e]] = x[e];
    if (S > 0) {
        double E[N];
        for (int i = 0; i < N; ++i) {
            double s = hQ[i];
            for (int j = 0; j < N; ++j) s += M[i * N + j] * a[j];
            E[i] = s;
        }
        multipliers(E, DEP0, D, Jh, piv, lam);
    }
    for (int i = 0; i < N; ++i) if (!isfinite(a[i])) return 1;
    for (int r = 0; r < S; ++r) if (!isfinite(lam[r])) return 1;
    return 0;
}

/* A rigid-body tree's accelerations, multipliers and every joint's reaction in one call: the
   recursions' blocks (rigid.c), the tree's factors of M (rigid_solve; else the dense split of
   solver.c with the default partition DEP0), then the wrenches at those accelerations
   (rigid_wrenches_after, from the pass at a = 0).
   Accelerations NaN where both fail (the partition is unusable or C^T M C singular): the caller
   then takes the general route. */
void appell_forward(double t, const double *restrict q, const double *restrict w, const double *restrict a,
                    const double *restrict p, double *restrict acc, double *restrict lam, double *restrict wrench)
{
    double Rr[9 * NB], r[3 * NB], Sc[6 * N], cb[6 * NB], in[10 * NB], base[6], Q[N], g[3], o[3 * NB];
    double Re[9 * NB], re[3 * NB], v[6 * NB], acc_b[6 * NB], f[6 * NB];
    double M[N * N], hQ[N], J[DIM(S * N)], c[DIM(S)], R[N], mult[DIM(S)];
    struct rigid_constants own;
    (void)a;
    appell_rigid_terms(t, q, w, 0, p, Rr, r, Sc, cb, in, base, Q, J, c);   /* the terms once */
    appell_rigid_points(t, q, w, 0, p, g, o);
    const struct rigid_constants *k = rigid_constants_at(p, Rr, r, in, &own);
    hanging(Rr, r, k, Re, re);
    rigid_blocks(Re, re, Sc, cb, k, base, Q, w, M, hQ, v, acc_b, f);
    if (rigid_solve(M, hQ, J, c, acc, mult) &&
        appell_split(M, hQ, J, c, DEP0, KEEP_CONDITION, acc, mult, R)) {
        for (int i = 0; i < N; ++i) acc[i] = NAN;
        return;
    }
    for (int k = 0; k < S; ++k) lam[k] = mult[k];
    rigid_wrenches_after(Rr, r, Re, re, Sc, k, g, o, base, acc, v, acc_b, f, wrench);
}
