/* The yardstick of benchmarks/loop.py: the classical fixed-step Runge-Kutta method of order 4
   written in C around a model compiled by appell (its entry points appell_evaluate and
   appell_residuals, passed as function pointers), recording at every step what appell's
   simulate records: the state, the accelerations, the multipliers and the residuals. */
#include <stdlib.h>
#include <string.h>

typedef int (*evaluate_fn)(double t, const double *y, const double *p, const double *bias, const int *dep,
                           double cond_max, double *dy, double *lam);
typedef void (*residuals_fn)(double t, const double *q, const double *w, const double *a, const double *p,
                             double *F, double *phi);

/* rows k = 0..steps at t0 + k h; 0, or 1 when the compiled split refused a state */
int rk4_run(evaluate_fn ev, residuals_fn res, const double *p, const int *dep, double cond_max,
            int nq, int n, int s, double t0, const double *y0, double h, long steps,
            double *Y, double *A, double *L, double *F, double *PHI)
{
    int ny = nq + n, st = 0;
    double *mem = malloc(sizeof(double) * (6 * ny + (s > 0 ? s : 1)));
    double *y = mem, *yt = y + ny, *k1 = yt + ny, *k2 = k1 + ny, *k3 = k2 + ny, *k4 = k3 + ny, *lam = k4 + ny;
    memcpy(y, y0, sizeof(double) * ny);
    for (long k = 0; k <= steps; ++k) {
        double t = t0 + k * h;
        if (ev(t, y, p, NULL, dep, cond_max, k1, lam)) { st = 1; break; }
        memcpy(Y + k * ny, y, sizeof(double) * ny);
        memcpy(A + k * n, k1 + nq, sizeof(double) * n);
        memcpy(L + k * s, lam, sizeof(double) * s);
        res(t, y, y + nq, NULL, p, F + k * s, PHI + k * s);
        if (k == steps) break;
        for (int i = 0; i < ny; ++i) yt[i] = y[i] + 0.5 * h * k1[i];
        if (ev(t + 0.5 * h, yt, p, NULL, dep, cond_max, k2, lam)) { st = 1; break; }
        for (int i = 0; i < ny; ++i) yt[i] = y[i] + 0.5 * h * k2[i];
        if (ev(t + 0.5 * h, yt, p, NULL, dep, cond_max, k3, lam)) { st = 1; break; }
        for (int i = 0; i < ny; ++i) yt[i] = y[i] + h * k3[i];
        if (ev(t + h, yt, p, NULL, dep, cond_max, k4, lam)) { st = 1; break; }
        for (int i = 0; i < ny; ++i) y[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
    }
    free(mem);
    return st;
}
