
/* A rigid-body tree's accelerations, multipliers and every joint's reaction in one call: the
   recursions' blocks (rigid.c), the dense split of solver.c with the default partition DEP0,
   then the wrenches at those accelerations. Accelerations NaN where the split fails (the
   partition is unusable or C^T M C singular): the caller then takes the general route. */
void appell_forward(double t, const double *restrict q, const double *restrict w, const double *restrict a,
                    const double *restrict p, double *restrict acc, double *restrict lam, double *restrict wrench)
{
    double Rr[9 * NB], r[3 * NB], Sc[6 * N], cb[6 * NB], in[10 * NB], base[6], Q[N], g[3], o[3 * NB];
    double Y[10 * NB], Ym[10 * NB];
    double M[N * N], hQ[N], J[DIM(S * N)], c[DIM(S)], R[N], mult[DIM(S)];
    (void)a;
    appell_rigid_terms(t, q, w, 0, p, Rr, r, Sc, cb, in, base, Q, J, c);   /* the terms once */
    appell_rigid_points(t, q, w, 0, p, g, o);
    rigid_inertias(Rr, r, in, Y, Ym);
    rigid_blocks(Rr, r, Sc, cb, Ym, base, Q, w, M, hQ);
    if (appell_split(M, hQ, J, c, DEP0, KEEP_CONDITION, acc, mult, R)) {
        for (int i = 0; i < N; ++i) acc[i] = NAN;
        return;
    }
    for (int k = 0; k < S; ++k) lam[k] = mult[k];
    rigid_wrenches(Rr, r, Sc, cb, Y, g, o, w, acc, wrench);
}
