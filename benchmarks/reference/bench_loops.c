/* Timing loop in C for appell's compiled closed chain (benchmarks/closed_chains.py builds and runs
   it): appell_loop_evaluate (the accelerations, every multiplier and every joint's wrench) at one
   state, the per-call CPU time of the best and the median of 41 rounds (CLOCK_PROCESS_CPUTIME_ID, as
   the harness and pinocchio_loop.cpp).
   usage: bench_loops LIB iterations nq n nu np nc nb q... w... p...   (prints JSON) */
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

typedef void (*evaluate_t)(double, const double *, const double *, const double *, const double *, double *,
                           double *, double *, double *);

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);  /* CPU time, as benchmarks/harness.py */
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

int main(int argc, char **argv)
{
    if (argc < 9) return 2;
    void *lib = dlopen(argv[1], RTLD_NOW);
    if (!lib) { fprintf(stderr, "%s\n", dlerror()); return 2; }
    evaluate_t ev = (evaluate_t)dlsym(lib, "appell_loop_evaluate");
    if (!ev) { fprintf(stderr, "no appell_loop_evaluate\n"); return 2; }
    const int iters = atoi(argv[2]), nq = atoi(argv[3]), n = atoi(argv[4]), nu = atoi(argv[5]), np = atoi(argv[6]);
    const int nc = atoi(argv[7]), nb = atoi(argv[8]);
    if (argc != 9 + nq + n + np) { fprintf(stderr, "expected %d numbers\n", nq + n + np); return 2; }
    double *q = calloc(nq + 1, sizeof(double)), *w = calloc(n + 1, sizeof(double)), *u = calloc(nu + 1, sizeof(double));
    double *p = calloc(np + 1, sizeof(double)), *a = calloc(n + 1, sizeof(double)), *lam = calloc(nc + 1, sizeof(double));
    double *wrench = calloc(6 * nb + 1, sizeof(double)), status = 0.0, per[41], sink = 0.0;
    for (int i = 0; i < nq; ++i) q[i] = atof(argv[9 + i]);
    for (int i = 0; i < n; ++i) w[i] = atof(argv[9 + nq + i]);
    for (int i = 0; i < np; ++i) p[i] = atof(argv[9 + nq + n + i]);
    for (int rep = 0; rep < 41; ++rep) {
        double t0 = now();
        for (int it = 0; it < iters; ++it) { q[0] += 1e-300; ev(0.0, q, w, u, p, a, lam, wrench, &status); sink += wrench[0]; }
        per[rep] = (now() - t0) / iters;
    }
    for (int i = 1; i < 41; ++i)                         /* insertion sort of the rounds */
        for (int j = i; j > 0 && per[j] < per[j - 1]; --j) { double x = per[j]; per[j] = per[j - 1]; per[j - 1] = x; }
    printf("{\"appell_ns\": %.1f, \"appell_median_ns\": %.1f, \"status\": %g, \"a0\": %.17g, \"sink\": %g}\n",
           per[0] * 1e9, per[20] * 1e9, status, a[0], sink * 0);
    return 0;
}
