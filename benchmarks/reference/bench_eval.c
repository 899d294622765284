/* Timing loop in C, the candidates interleaved: appell's generated appell_evaluate (from the
 * shared library given on the command line), the dense hand-written nlink_evaluate (nlink.c)
 * and the O(n) nlink_recursive (nlink_recursive.c), all at the same n-link state.
 * Each of `rounds` rounds times `iters` calls of each candidate in turn; the per-call time
 * printed is the median over rounds, and each ratio is the median of the per-round ratios.
 * usage: bench_eval LIB n iterations dependent y_1..y_2n p_1..p_2n+2   (prints JSON)
 * LIB may be "-" (no appell library: only the two references). */
#include <dlfcn.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

int nlink_evaluate(int n, const double *y, const double *p, double *dy, double *lam);
int nlink_recursive(int n, const double *y, const double *p, double *dy, double *lam);
typedef int (*appell_eval_t)(double, const double *, const double *, const double *, const int *, double,
                             double *, double *);

#define ROUNDS 15

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);   /* CPU time: robust on a shared machine */
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

static int cmp(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double median(double *v, int k)
{
    qsort(v, k, sizeof(double), cmp);
    return k % 2 ? v[k / 2] : 0.5 * (v[k / 2 - 1] + v[k / 2]);
}

static double maxdiff(int n, const double *a, double la, const double *b, double lb)
{
    double d = fabs(la - lb);
    for (int i = 0; i < 2 * n; ++i) if (fabs(a[i] - b[i]) > d) d = fabs(a[i] - b[i]);
    return d;
}

int main(int argc, char **argv)
{
    if (argc < 5) return 2;
    appell_eval_t ev = 0;
    if (strcmp(argv[1], "-") != 0) {
        void *lib = dlopen(argv[1], RTLD_NOW);
        if (!lib) { fprintf(stderr, "%s\n", dlerror()); return 2; }
        ev = (appell_eval_t)dlsym(lib, "appell_evaluate");
        if (!ev) { fprintf(stderr, "no appell_evaluate in %s\n", argv[1]); return 2; }
    }
    int n = atoi(argv[2]), iters = atoi(argv[3]);
    if (argc != 5 + 4 * n + 2) { fprintf(stderr, "expected %d numbers\n", 4 * n + 2); return 2; }
    double *y = malloc(sizeof(double) * 2 * n), *p = malloc(sizeof(double) * (2 * n + 2));
    double *dya = calloc(2 * n, sizeof(double)), *dyd = calloc(2 * n, sizeof(double));
    double *dyr = calloc(2 * n, sizeof(double)), la = 0.0, ld = 0.0, lr = 0.0;
    for (int i = 0; i < 2 * n; ++i) y[i] = atof(argv[5 + i]);
    for (int i = 0; i < 2 * n + 2; ++i) p[i] = atof(argv[5 + 2 * n + i]);
    int dep = atoi(argv[4]);   /* appell's dependent acceleration (s = 1) */
    double ta[ROUNDS], td[ROUNDS], tr[ROUNDS], ra[ROUNDS], rd[ROUNDS], sink = 0.0, y0 = y[0];
    for (int rep = 0; rep < ROUNDS; ++rep) {
        /* y[0] moves by 1e-300 per call so that no call can be hoisted out of the loop */
        double t0 = now();
        if (ev) for (int it = 0; it < iters; ++it) { y[0] += 1e-300; ev(0.0, y, p, 0, &dep, 1e8, dya, &la); sink += la; }
        double t1 = now();
        for (int it = 0; it < iters; ++it) { y[0] += 1e-300; nlink_evaluate(n, y, p, dyd, &ld); sink += ld; }
        double t2 = now();
        for (int it = 0; it < iters; ++it) { y[0] += 1e-300; nlink_recursive(n, y, p, dyr, &lr); sink += lr; }
        double t3 = now();
        ta[rep] = (t1 - t0) / iters; td[rep] = (t2 - t1) / iters; tr[rep] = (t3 - t2) / iters;
        ra[rep] = ta[rep] / tr[rep]; rd[rep] = td[rep] / tr[rep];
    }
    y[0] = y0;
    if (ev) ev(0.0, y, p, 0, &dep, 1e8, dya, &la);
    nlink_evaluate(n, y, p, dyd, &ld);
    nlink_recursive(n, y, p, dyr, &lr);
    double diff_dense = maxdiff(n, dyd, ld, dyr, lr), diff_appell = ev ? maxdiff(n, dya, la, dyr, lr) : -1.0;
    printf("{\"appell_ns\": %.2f, \"dense_ns\": %.2f, \"recursive_ns\": %.2f, "
           "\"appell_over_recursive\": %.3f, \"dense_over_recursive\": %.3f, "
           "\"max_abs_diff_appell\": %.3g, \"max_abs_diff_dense\": %.3g, \"has_appell\": %d, \"sink\": %g}\n",
           ev ? median(ta, ROUNDS) * 1e9 : -1.0, median(td, ROUNDS) * 1e9, median(tr, ROUNDS) * 1e9,
           ev ? median(ra, ROUNDS) : -1.0, median(rd, ROUNDS), diff_appell, diff_dense, ev != 0, sink * 0);
    return 0;
}
