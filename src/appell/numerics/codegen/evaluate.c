
/* dy/dt = (K w + k, a) and the multipliers, in one call */
int appell_evaluate(double t, const double *y, const double *p, const double *bias, const int *dep,
                    double cond_max, double *dy, double *lam)
{
    double R[N];
    appell_rates(t, y, y + NQ, 0, p, dy);
    return appell_solve(t, y, y + NQ, p, bias, dep, cond_max, dy + NQ, lam, R);
}
