/* Timing loop in C: appell's generated appell_evaluate (shared library given on the command
 * line) against the hand-written O(n) recursion nlink_aba_evaluate (nlink_aba.c), same state.
 * usage: bench_aba LIB n iterations dependent y_1..y_2n p_1..p_2n+2   (prints JSON) */
#include <dlfcn.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

int nlink_aba_evaluate(int n, const double *y, const double *p, double *dy, double *lam);
typedef int (*appell_eval_t)(double, const double *, const double *, const double *, const int *, double,
                             double *, double *);

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

int main(int argc, char **argv)
{
    if (argc < 5) return 2;
    void *lib = dlopen(argv[1], RTLD_NOW);
    if (!lib) { fprintf(stderr, "%s\n", dlerror()); return 2; }
    appell_eval_t ev = (appell_eval_t)dlsym(lib, "appell_evaluate");
    int n = atoi(argv[2]), iters = atoi(argv[3]), dep = atoi(argv[4]);
    if (argc != 5 + 4 * n + 2) { fprintf(stderr, "expected %d numbers\n", 4 * n + 2); return 2; }
    double *y = malloc(sizeof(double) * 2 * n), *p = malloc(sizeof(double) * (2 * n + 2));
    double *dy1 = malloc(sizeof(double) * 2 * n), *dy2 = malloc(sizeof(double) * 2 * n), lam1, lam2;
    for (int i = 0; i < 2 * n; ++i) y[i] = atof(argv[5 + i]);
    for (int i = 0; i < 2 * n + 2; ++i) p[i] = atof(argv[5 + 2 * n + i]);
    double best_a = 1e9, best_r = 1e9, sink = 0.0, ratio[41];
    for (int rep = 0; rep < 41; ++rep) {      /* interleaved rounds: appell, then the recursion */
        double t0 = now();
        for (int it = 0; it < iters; ++it) { y[0] += 1e-300; ev(0.0, y, p, 0, &dep, 1e4, dy1, &lam1); sink += lam1; }
        double t1 = now();
        for (int it = 0; it < iters; ++it) { y[0] += 1e-300; nlink_aba_evaluate(n, y, p, dy2, &lam2); sink += lam2; }
        double t2 = now();
        if ((t1 - t0) / iters < best_a) best_a = (t1 - t0) / iters;
        if ((t2 - t1) / iters < best_r) best_r = (t2 - t1) / iters;
        ratio[rep] = (t1 - t0) / (t2 - t1);
    }
    for (int i = 1; i < 41; ++i)              /* median of the paired ratios (robust to load) */
        for (int j = i; j > 0 && ratio[j] < ratio[j - 1]; --j) { double x = ratio[j]; ratio[j] = ratio[j - 1]; ratio[j - 1] = x; }
    double scale = fabs(lam2), diff = fabs(lam1 - lam2);
    for (int i = 0; i < 2 * n; ++i) if (fabs(dy2[i]) > scale) scale = fabs(dy2[i]);
    for (int i = 0; i < 2 * n; ++i) if (fabs(dy1[i] - dy2[i]) > diff) diff = fabs(dy1[i] - dy2[i]);
    printf("{\"appell_c_ns\": %.1f, \"recursion_ns\": %.1f, \"median_ratio\": %.3f, \"max_rel_diff\": %.3g, \"sink\": %g}\n",
           best_a * 1e9, best_r * 1e9, ratio[20], diff / scale, sink * 0);
    return 0;
}
