
/* bias (may be NULL) is added to the constraints: f + bias = 0 */
int appell_solve(double t, const double *q, const double *w, const double *p, const double *bias,
                 const int *dep, double cond_max, double *a, double *lam, double *R)
{
    double M[N * N], hQ[N], J[DIM(S * N)], c[DIM(S)];
    appell_blocks(t, q, w, 0, p, M, hQ, J, c);
    if (bias) for (int r = 0; r < S; ++r) c[r] += bias[r];
    return appell_split(M, hQ, J, c, dep, cond_max, a, lam, R);
}
