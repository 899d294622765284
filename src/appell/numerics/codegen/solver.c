
/* DIM(k): an array size of at least 1 (the header defines it) */

static int lu_factor(int n, double *A, int *piv)
{
    for (int k = 0; k < n; ++k) {
        int r = k;
        double big = fabs(A[k * n + k]);
        for (int i = k + 1; i < n; ++i)
            if (fabs(A[i * n + k]) > big) { big = fabs(A[i * n + k]); r = i; }
        piv[k] = r;
        if (!(big > 0.0)) return 1;
        if (r != k)
            for (int j = 0; j < n; ++j) { double x = A[k * n + j]; A[k * n + j] = A[r * n + j]; A[r * n + j] = x; }
        for (int i = k + 1; i < n; ++i) {
            double f = A[i * n + k] /= A[k * n + k];
            for (int j = k + 1; j < n; ++j) A[i * n + j] -= f * A[k * n + j];
        }
    }
    return 0;
}

/* A x = b with P A = L U */
static void lu_solve(int n, const double *LU, const int *piv, double *b)
{
    for (int k = 0; k < n; ++k) if (piv[k] != k) { double x = b[k]; b[k] = b[piv[k]]; b[piv[k]] = x; }
    for (int i = 0; i < n; ++i) for (int j = 0; j < i; ++j) b[i] -= LU[i * n + j] * b[j];
    for (int i = n - 1; i >= 0; --i) {
        for (int j = i + 1; j < n; ++j) b[i] -= LU[i * n + j] * b[j];
        b[i] /= LU[i * n + i];
    }
}

/* A^T x = b: U^T y = b, L^T z = y, x = P^T z */
static void lu_solve_t(int n, const double *LU, const int *piv, double *b)
{
    for (int i = 0; i < n; ++i) {
        for (int j = 0; j < i; ++j) b[i] -= LU[j * n + i] * b[j];
        b[i] /= LU[i * n + i];
    }
    for (int i = n - 1; i >= 0; --i) for (int j = i + 1; j < n; ++j) b[i] -= LU[j * n + i] * b[j];
    for (int k = n - 1; k >= 0; --k) if (piv[k] != k) { double x = b[k]; b[k] = b[piv[k]]; b[piv[k]] = x; }
}

static double norm1(int n, const double *A)
{
    double best = 0.0;
    for (int j = 0; j < n; ++j) {
        double s = 0.0;
        for (int i = 0; i < n; ++i) s += fabs(A[i * n + j]);
        if (s > best) best = s;
    }
    return best;
}

/* Row scales D = 1 / max_j |J_rj|, the LU factors of D J_h and the partition's relative condition
   number kappa = |(D J_h)^{-1}|_1 |D J|_1 (numeric.partition_condition), stored in *kappa. 0: usable;
   1: kappa reaches cond_max or a row of J vanishes (Python switches the partition or names the
   singular constraints) */
static int scaled_block(const double *J, const int *dep, double cond_max, double *D, double *Jh, int *piv,
                        double *kappa)
{
    *kappa = INFINITY;
    double inv[DIM(S * S)], nrm = 0.0;
    for (int r = 0; r < S; ++r) {
        double big = 0.0;
        for (int i = 0; i < N; ++i) if (fabs(J[r * N + i]) > big) big = fabs(J[r * N + i]);
        if (!(big > 0.0) || !isfinite(big)) return 1;
        D[r] = 1.0 / big;
    }
    for (int i = 0; i < N; ++i) {
        double s = 0.0;
        for (int r = 0; r < S; ++r) s += fabs(J[r * N + i]) * D[r];
        if (s > nrm) nrm = s;
    }
    for (int r = 0; r < S; ++r) for (int k = 0; k < S; ++k) Jh[r * S + k] = D[r] * J[r * N + dep[k]];
    if (lu_factor(S, Jh, piv)) return 1;
    for (int k = 0; k < S; ++k) {          /* columns of (D J_h)^{-1}, for kappa */
        double e[DIM(S)];
        for (int r = 0; r < S; ++r) e[r] = (r == k);
        lu_solve(S, Jh, piv, e);
        for (int r = 0; r < S; ++r) inv[r * S + k] = e[r];
    }
    *kappa = nrm * norm1(S, inv);
    return !(*kappa < cond_max);
}

/* (1.5): lambda = D (D J_h)^{-T} E_h with E = M a + h - Q */
static void multipliers(const double *E, const int *dep, const double *D, const double *Jh, const int *piv,
                        double *lam)
{
    if (S > 0) {
        for (int r = 0; r < S; ++r) lam[r] = E[dep[r]];
        lu_solve_t(S, Jh, piv, lam);
        for (int r = 0; r < S; ++r) lam[r] *= D[r];
    }
}

/* R = J^T lambda; 2 if a or lambda is not finite */
static int finish(const double *J, const double *a, const double *lam, double *R)
{
    for (int i = 0; i < N; ++i) {
        double s = 0.0;
        for (int r = 0; r < S; ++r) s += J[r * N + i] * lam[r];
        R[i] = s;
    }
    for (int i = 0; i < N; ++i) if (!isfinite(a[i])) return 2;
    for (int r = 0; r < S; ++r) if (!isfinite(lam[r])) return 2;
    return 0;
}

/* One pass of the split (steps 2-4) for a and lambda; *kappa the partition's condition number.
   0: solved; 1: the partition is unusable (scaled_block); 2: C^T M C singular */
static int split_once(const double *M, const double *hQ, const double *J, const double *c, const int *dep,
                      double cond_max, double *kappa, double *a, double *lam)
{
    int isdep[N] = {0}, ind[DIM(P)], piv[DIM(S)], pivA[DIM(P)];
    double Jh[DIM(S * S)], D[DIM(S)], X[DIM(S * P)], d[N], A[DIM(P * P)], b[DIM(P)];
    double MC[DIM(N * P)], Md[N], E[N];
    for (int k = 0; k < S; ++k) isdep[dep[k]] = 1;
    for (int i = 0, j = 0; i < N; ++i) if (!isdep[i]) ind[j++] = i;
    for (int i = 0; i < N; ++i) d[i] = 0.0;
    if (S > 0) {
        if (scaled_block(J, dep, cond_max, D, Jh, piv, kappa)) return 1;
        for (int j = 0; j < P; ++j) {           /* X = J_h^{-1} J_nu = (D J_h)^{-1} D J_nu */
            double col[DIM(S)];
            for (int r = 0; r < S; ++r) col[r] = D[r] * J[r * N + ind[j]];
            lu_solve(S, Jh, piv, col);
            for (int r = 0; r < S; ++r) X[r * P + j] = col[r];
        }
        double dh[DIM(S)];                      /* d_h = -J_h^{-1} c */
        for (int r = 0; r < S; ++r) dh[r] = -D[r] * c[r];
        lu_solve(S, Jh, piv, dh);
        for (int r = 0; r < S; ++r) d[dep[r]] = dh[r];
    }
    if (P > 0) {
        /* MC = M C with C = [I; -X] (rows ind: identity, rows dep: -X) */
        for (int i = 0; i < N; ++i)
            for (int j = 0; j < P; ++j) {
                double s = M[i * N + ind[j]];
                for (int r = 0; r < S; ++r) s -= M[i * N + dep[r]] * X[r * P + j];
                MC[i * P + j] = s;
            }
        for (int i = 0; i < N; ++i) {
            double s = hQ[i];
            for (int r = 0; r < S; ++r) s += M[i * N + dep[r]] * d[dep[r]];
            Md[i] = s;                          /* M d + h - Q */
        }
        for (int j = 0; j < P; ++j) {           /* A = C^T M C, b = -C^T (M d + h - Q) */
            for (int k = 0; k < P; ++k) {
                double s = MC[ind[j] * P + k];
                for (int r = 0; r < S; ++r) s -= X[r * P + j] * MC[dep[r] * P + k];
                A[j * P + k] = s;
            }
            double s = Md[ind[j]];
            for (int r = 0; r < S; ++r) s -= X[r * P + j] * Md[dep[r]];
            b[j] = -s;
        }
        if (lu_factor(P, A, pivA)) return 2;
        lu_solve(P, A, pivA, b);
        for (int j = 0; j < P; ++j) a[ind[j]] = b[j];
        for (int r = 0; r < S; ++r) {
            double s = d[dep[r]];
            for (int j = 0; j < P; ++j) s -= X[r * P + j] * b[j];
            a[dep[r]] = s;
        }
    } else {
        for (int i = 0; i < N; ++i) a[i] = d[i];
    }
    for (int i = 0; i < N; ++i) {
        double s = hQ[i];
        for (int j = 0; j < N; ++j) s += M[i * N + j] * a[j];
        E[i] = s;
    }
    multipliers(E, dep, D, Jh, piv, lam);
    return 0;
}

/* The split (1.4)/(1.5), refined once where the partition's condition number reaches
   REFINE_CONDITION (numeric.split_solve): with the residuals r = M a + h - Q - J^T lambda and
   s = J a + c of the first pass, the same split gives the corrections (da, dlambda) of
   M da - J^T dlambda = -r, J da = -s. 0: solved; 1: the partition is unusable; 2: not finite or
   C^T M C singular */
int appell_split(const double *M, const double *hQ, const double *J, const double *c, const int *dep,
                 double cond_max, double *a, double *lam, double *R)
{
    double kappa = 1.0;
    int status = split_once(M, hQ, J, c, dep, cond_max, &kappa, a, lam);
    if (status) return status;
    if (S > 0 && kappa >= REFINE_CONDITION) {
        double r[N], s[DIM(S)], da[N], dl[DIM(S)], k2;
        for (int i = 0; i < N; ++i) {
            double v = hQ[i];
            for (int j = 0; j < N; ++j) v += M[i * N + j] * a[j];
            for (int k = 0; k < S; ++k) v -= J[k * N + i] * lam[k];
            r[i] = v;
        }
        for (int k = 0; k < S; ++k) {
            double v = c[k];
            for (int i = 0; i < N; ++i) v += J[k * N + i] * a[i];
            s[k] = v;
        }
        status = split_once(M, r, J, s, dep, INFINITY, &k2, da, dl);
        if (status) return status;
        for (int i = 0; i < N; ++i) a[i] += da[i];
        for (int k = 0; k < S; ++k) lam[k] += dl[k];
    }
    return finish(J, a, lam, R);
}

