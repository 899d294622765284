/* appell: the compiled integration loop (appell.numerics.compiled_loop).

   DOP853, the explicit Runge-Kutta pair of orders 8(5,3) of Dormand and Prince with the
   step-size control and the dense output of order 7 of Hairer, Norsett and Wanner, "Solving
   Ordinary Differential Equations I", 2nd ed., Springer 1993, section II.10 (their code
   dop853.f); the same scheme and control as SciPy's ``scipy.integrate.DOP853`` (its reference
   in the tests): error norm |h| |e5|^2 / sqrt(len (|e5|^2 + 0.01 |e3|^2)) with the scale
   atol + rtol max(|y|, |y_new|), step factor 0.9 err^(-1/8) clipped to [0.2, 10] (not above
   1 after a rejection), the initial step of Hairer-Norsett-Wanner II.4.

   It integrates a model compiled by appell.numerics.codegen through the model library's
   entry points (function pointers appell_evaluate and appell_residuals), and records the
   output times inside each accepted step: the state from the dense output, the model
   evaluated there (accelerations, multipliers) and the constraint residuals. Where the
   compiled split refuses a state (the partition's condition number reached its limit, or a
   value is not finite) a Python callback evaluates it instead (the switch of partition),
   and it is called again at the first state the compiled split accepts afterwards (so that
   Python logs the return of the partition). The loop returns to Python after a step whose
   end needs it: the final time is reached, a projection onto the constraints is due that
   the loop cannot do itself (below), the budget of evaluations is spent, or every step when
   Python watches events.

   The projection (appell.simulation.projection, switched on by appell_loop_projection): where
   a step's end has a constraint residual above projection_tol, the loop records the output
   times inside the step from its dense output, projects the end onto the constraints as
   appell.simulation.projection.project does (Newton's method with minimum-norm steps
   dq = -F_q^+ F on the holonomic rows, F_q by central differences of appell_residuals with
   the steps 1e-7 max(1, |q_j|) of numeric.difference_jacobian; then dw = -phi_w^+ phi with
   phi_w = J = df/da from appell_blocks, which equals the velocity residual's Jacobian for
   every constraint linear in a; each step by Householder QR of the rows' transpose), and
   restarts there keeping its step size, as Python's restart does. It leaves the projection
   to Python where Python's answer could differ: a Jacobian whose rows are nearly dependent
   (a diagonal entry of R below PROJECTION_RANK of the largest, where numpy.linalg.lstsq's
   cut-off could drop a direction), more rows than columns, a value not finite, a Newton
   iteration that does not converge, or Python's partition in use.

   The rank watch (appell.simulation.singular): with appell_loop_watch, the loop follows
   g~ = sqrt of the smallest pivot of the pivoted Cholesky factorisation of (D0 J)(D0 J)^T
   at every step's end (D0 the start scaling of the constraint rows; g~ >= sigma_min(D0 J))
   and returns to Python where g~ at the previous step's end is a local minimum with a dip,
   or g~ falls below the level: Python then minimises the exact measure over the last two
   steps, the previous one through appell_loop_dense_previous (its stages are kept). A
   projection in the loop moves the state by the residual alone: the watch's history goes
   on across it, and the projected step stays the previous one of the next. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define NS 12   /* stages of a step (the 13th is f at the step's end) */
#define NK 16   /* with the three stages of the dense output */
#define NF 7    /* coefficient vectors of the interpolant */
#define PROJECTION_TOL 1e-13   /* Newton's target of appell.simulation.projection.project */
#define PROJECTION_ITER 20     /* its iterations per level */
#define PROJECTION_FAIL 1e-9   /* the residual above which project() fails */
#define PROJECTION_RANK 1e-6   /* |R_kk| below this of the largest: rows nearly dependent, Python projects */

/* coefficients of Hairer's dop853.f (c_i, a_ij, b_i, the error weights of orders 5 and 3,
   and the dense-output weights d_ij) */
static const double C_[NK] = {0, 0.05260015195876773, 0.078900227938151601, 0.1183503419072274, 0.28164965809277259, 0.33333333333333331, 0.25, 0.30769230769230771, 0.6512820512820513, 0.59999999999999998, 0.8571428571428571, 1, 1, 0.10000000000000001, 0.20000000000000001, 0.77777777777777779};
static const double A_[NK][NK] = {
    {0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0},
    {0.05260015195876773, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0},
    {0.0197250569845379, 0.059175170953613701, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0},
    {0.029587585476806851, 0, 0.088762756430420545, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0},
    {0.24136513415926669, 0, -0.88454947932828609, 0.92483400326179199, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0},
    {0.037037037037037035, 0, 0, 0.17082860872947386, 0.12546768756682242, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0},
    {0.037109375, 0, 0, 0.17025221101954405, 0.060216538980455959, -0.017578125, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0},
    {0.037092000118504789, 0, 0, 0.17038392571223998, 0.10726203044637328, -0.015319437748624402, 0.0082737891638140233, 0, 0, 0, 0, 0, 0, 0, 0, 0},
    {0.62411095871607569, 0, 0, -3.3608926294469414, -0.86821934684172597, 27.59209969944671, 20.154067550477894, -43.489884181069961, 0, 0, 0, 0, 0, 0, 0, 0},
    {0.47766253643826434, 0, 0, -2.4881146199716677, -0.59029082683684297, 21.230051448181193, 15.279233632882423, -33.288210968984863, -0.020331201708508627, 0, 0, 0, 0, 0, 0, 0},
    {-0.9371424300859873, 0, 0, 5.1863724288440638, 1.0914373489967295, -8.1497870107469268, -18.520065659996959, 22.739487099350505, 2.4936055526796523, -3.0467644718982196, 0, 0, 0, 0, 0, 0},
    {2.273310147516538, 0, 0, -10.534495466737249, -2.0008720582248625, -17.958931863118799, 27.94888452941996, -2.8589982771350235, -8.8728569335306293, 12.360567175794303, 0.64339274601576357, 0, 0, 0, 0, 0},
    {0.054293734116568765, 0, 0, 0, 0, 4.4503128927524092, 1.8915178993145003, -5.8012039600105849, 0.3111643669578199, -0.15216094966251609, 0.20136540080403034, 0.044710615727772587, 0, 0, 0, 0},
    {0.056167502283047954, 0, 0, 0, 0, 0, 0.25350021021662483, -0.2462390374708025, -0.12419142326381637, 0.15329179827876568, 0.0082010522956346907, 0.0075678976605456994, -0.0082979999999999998, 0, 0, 0},
    {0.031834648163502142, 0, 0, 0, 0, 0.028300909672366776, 0.053541988307438566, -0.054923748571390991, 0, 0, -0.00010834732869724932, 0.00038257109083565839, -0.00034046500868740456, 0.1413124436746325, 0, 0},
    {-0.42889630158379194, 0, 0, 0, 0, -4.697621415361164, 7.6834211960625991, 4.0689898183971103, 0.35672718745528109, 0, 0, 0, -0.0013990241651590145, 2.9475147891527724, -9.1509584721798696, 0},
};
static const double B_[NS] = {0.054293734116568765, 0, 0, 0, 0, 4.4503128927524092, 1.8915178993145003, -5.8012039600105849, 0.3111643669578199, -0.15216094966251609, 0.20136540080403034, 0.044710615727772587};
static const double E3_[NS + 1] = {-0.18980075407240762, 0, 0, 0, 0, 4.4503128927524092, 1.8915178993145003, -5.8012039600105849, -0.42268232132379191, -0.15216094966251609, 0.20136540080403034, 0.022651792198360821, 0};
static const double E5_[NS + 1] = {0.01312004499419488, 0, 0, 0, 0, -1.2251564463762044, -0.4957589496572502, 1.6643771824549864, -0.35032884874997366, 0.33417911871301748, 0.08192320648511571, -0.022355307863886294, 0};
static const double D_[NF - 3][NK] = {
    {-8.4289382761090135, 0, 0, 0, 0, 0.56671495351937773, -3.0689499459498917, 2.3846676565120699, 2.1170345824450281, -0.87139158377797299, 2.2404374302607883, 0.63157877876946877, -0.088990336451333307, 18.148505520854727, -9.194632392478356, -4.4360363875948936},
    {10.427508642579134, 0, 0, 0, 0, 242.28349177525817, 165.20045171727028, -374.5467547226902, -22.113666853125306, 7.7334326684722638, -30.674084731089398, -9.3321305264302286, 15.697238121770845, -31.139403219565178, -9.3529243588444793, 35.816841486394082},
    {19.985053242002433, 0, 0, 0, 0, -387.03730874935178, -189.17813819516758, 527.80815920542364, -11.573902539959629, 6.8812326946963003, -1.0006050966910838, 0.77771377980534429, -2.7782057523535082, -60.196695231264123, 84.320405506677162, 11.992291136182789},
    {-25.69393346270375, 0, 0, 0, 0, -154.18974869023643, -231.5293791760455, 357.63911791061412, 93.405324183624316, -37.458323136451632, 104.0996495089623, 29.840293426660502, -43.533456590011141, 96.324553959188279, -39.177261675615441, -149.72683625798564},
};

typedef int (*evaluate_fn)(double t, const double *y, const double *p, const double *bias, const int *dep,
                           double cond_max, double *dy, double *lam);
typedef void (*residuals_fn)(double t, const double *q, const double *w, const double *a, const double *p,
                             double *F, double *phi);
/* Python's evaluation: 0 done with the derivation's partition, 1 done with another, -1 failed */
typedef int (*fallback_fn)(double t, const double *y, double *dy, double *lam);
typedef void (*blocks_fn)(double t, const double *q, const double *w, const double *a, const double *p,
                          double *M, double *hQ, double *J, double *c);

typedef struct {
    int nq, n, s, ny;
    evaluate_fn evaluate;
    residuals_fn residuals;
    fallback_fn fallback;
    const double *p;
    const int *dep;
    double cond_max;
    int baumgarte;
    double alpha, beta;
    int switched;               /* Python's partition differs from the derivation's */
    double rtol, atol, max_step, t_bound;
    double t, t_old, h_abs, h_prev;
    long nfev, steps;
    int dense_ready;
    double *mem;                /* the work arrays, one allocation */
    double *y, *y_old, *f, *lam, *K, *Fd, *ytmp, *bias, *Fr, *phi, *dyt, *lamt;
    const double *t_eval;
    long n_eval;
    double *rec_y, *rec_acc, *rec_lam, *rec_F, *rec_phi;
    /* the rank watch (NULL blocks: off) and the previous step (its stages, for its dense output) */
    blocks_fn blocks;
    const double *wscale;
    double wlevel, wdip, g0, g1;
    double *wmem, *wM, *whQ, *wJ, *wc, *wG;
    int have_prev, prev_dense_ready;
    int prev_kept;              /* a projection kept its step as the previous one (the next step keeps it) */
    double p_t_old, p_t, p_h;
    double *p_y_old, *p_y, *p_f, *p_K, *p_Fd;
    /* the projection in the loop (NULL pblocks: Python projects) and the budget of evaluations */
    blocks_fn pblocks;
    double *pmem, *pM, *phQ, *pJ, *pc, *pA, *pz, *pyp, *pF, *pphi, *pFp, *pFm, *pb, *pRd, *ptau;
    int *prow;
    long projections;
} appell_loop;

appell_loop *appell_loop_new(int nq, int n, int s)
{
    appell_loop *c = calloc(1, sizeof(appell_loop));
    if (!c) return NULL;
    int ny = nq + n, sd = s > 0 ? s : 1;
    c->nq = nq; c->n = n; c->s = s; c->ny = ny;
    double *mem = calloc((size_t)ny * (5 + NK + NF) + 6 * (size_t)sd, sizeof(double));
    if (!mem) { free(c); return NULL; }
    c->mem = c->y = mem; c->y_old = c->y + ny; c->f = c->y_old + ny; c->ytmp = c->f + ny; c->dyt = c->ytmp + ny;
    c->K = c->dyt + ny; c->Fd = c->K + NK * ny;
    c->lam = c->Fd + NF * ny; c->bias = c->lam + sd; c->Fr = c->bias + sd; c->phi = c->Fr + sd;
    c->lamt = c->phi + sd;
    return c;
}

void appell_loop_free(appell_loop *c)
{
    if (c) { free(c->mem); free(c->wmem); free(c->pmem); free(c->prow); free(c); }
}

/* switch the projection in the loop on (header comment): blocks the model's appell_blocks.
   0, or -1 out of memory */
int appell_loop_projection(appell_loop *c, blocks_fn blocks)
{
    int n = c->n, s = c->s > 0 ? c->s : 1, ny = c->ny, m = c->nq > n ? c->nq : n;
    size_t size = (size_t)n * n + n + (size_t)s * n + s + (size_t)s * m + m + ny + 7 * (size_t)s;
    free(c->pmem);
    free(c->prow);
    c->pmem = calloc(size, sizeof(double));
    c->prow = calloc((size_t)s, sizeof(int));
    c->pblocks = NULL;
    if (!c->pmem || !c->prow) return -1;
    c->pM = c->pmem; c->phQ = c->pM + (size_t)n * n; c->pJ = c->phQ + n; c->pc = c->pJ + (size_t)s * n;
    c->pA = c->pc + s; c->pz = c->pA + (size_t)s * m; c->pyp = c->pz + m;
    c->pF = c->pyp + ny; c->pphi = c->pF + s; c->pFp = c->pphi + s; c->pFm = c->pFp + s; c->pb = c->pFm + s;
    c->pRd = c->pb + s; c->ptau = c->pRd + s;
    c->pblocks = blocks;
    return 0;
}

/* projections done in the loop since its creation */
long appell_loop_projections(const appell_loop *c) { return c->projections; }

void appell_loop_model(appell_loop *c, evaluate_fn evaluate, residuals_fn residuals, fallback_fn fallback,
                       const double *p, const int *dep, double cond_max, int baumgarte, double alpha, double beta)
{
    c->evaluate = evaluate; c->residuals = residuals; c->fallback = fallback;
    c->p = p; c->dep = dep; c->cond_max = cond_max;
    c->baumgarte = baumgarte; c->alpha = alpha; c->beta = beta;
}

void appell_loop_set_switched(appell_loop *c, int switched) { c->switched = switched; }

/* switch the rank watch on (header comment): blocks the model's appell_blocks, scale the s row
   scales D0, level and dip as in appell.simulation.singular. 0, or -1 out of memory */
int appell_loop_watch(appell_loop *c, blocks_fn blocks, const double *scale, double level, double dip)
{
    int n = c->n, s = c->s, ny = c->ny;
    size_t size = (size_t)n * n + n + (size_t)s * n + s + (size_t)s * s + (size_t)ny * (3 + NK + NF);
    free(c->wmem);
    c->wmem = calloc(size, sizeof(double));
    if (!c->wmem) { c->blocks = NULL; return -1; }
    c->wM = c->wmem; c->whQ = c->wM + (size_t)n * n; c->wJ = c->whQ + n; c->wc = c->wJ + (size_t)s * n;
    c->wG = c->wc + s; c->p_y_old = c->wG + (size_t)s * s; c->p_y = c->p_y_old + ny; c->p_f = c->p_y + ny;
    c->p_K = c->p_f + ny; c->p_Fd = c->p_K + NK * ny;
    c->blocks = blocks; c->wscale = scale; c->wlevel = level; c->wdip = dip;
    c->have_prev = 0; c->g0 = c->g1 = NAN;
    return 0;
}

/* g~ at (t, y): sqrt of the smallest pivot of pivoted Cholesky on G = (D0 J)(D0 J)^T */
static double watch_measure(appell_loop *c, double t, const double *y)
{
    int n = c->n, s = c->s;
    double *J = c->wJ, *G = c->wG;
    c->blocks(t, y, y + c->nq, NULL, c->p, c->wM, c->whQ, J, c->wc);
    for (int i = 0; i < s; ++i)
        for (int j = 0; j <= i; ++j) {
            double acc = 0.0;
            for (int k = 0; k < n; ++k) acc += J[i * n + k] * J[j * n + k];
            G[i * s + j] = G[j * s + i] = acc * c->wscale[i] * c->wscale[j];
        }
    double smallest = INFINITY;
    for (int k = 0; k < s; ++k) {
        int piv = k;
        for (int i = k + 1; i < s; ++i) if (G[i * s + i] > G[piv * s + piv]) piv = i;
        if (piv != k) {  /* symmetric swap of rows and columns k and piv */
            for (int j = 0; j < s; ++j) { double v = G[k * s + j]; G[k * s + j] = G[piv * s + j]; G[piv * s + j] = v; }
            for (int i = 0; i < s; ++i) { double v = G[i * s + k]; G[i * s + k] = G[i * s + piv]; G[i * s + piv] = v; }
        }
        double d = G[k * s + k];
        if (!(d > 0.0)) return isnan(d) ? INFINITY : 0.0;  /* not finite: left to the model's own checks */
        if (d < smallest) smallest = d;
        for (int i = k + 1; i < s; ++i) {
            double l = G[i * s + k] / d;
            for (int j = k + 1; j <= i; ++j) G[i * s + j] -= l * G[j * s + k];
        }
        for (int i = k + 1; i < s; ++i)
            for (int j = k + 1; j < i; ++j) G[j * s + i] = G[i * s + j];
    }
    return sqrt(smallest);
}

/* the watch after an accepted step: 1 when Python should look (a dip or the level), else 0 */
static int watch_step(appell_loop *c)
{
    double g = watch_measure(c, c->t, c->y);
    int look = g < c->wlevel || (c->g1 <= c->g0 && c->g1 <= g && c->g1 < c->wdip * fmax(c->g0, g));
    c->g0 = c->g1; c->g1 = g;
    return look;
}

static double nan0(double x) { return isnan(x) ? 0.0 : x; }

/* the larger of a and b, NaN if either is (as numpy.maximum; fmax would drop the NaN) */
static double max_nan(double a, double b) { return (isnan(a) || isnan(b)) ? NAN : (a > b ? a : b); }

/* dy/dt and the multipliers at (t, y): the compiled split (with the Baumgarte bias
   2 alpha phi + beta^2 F when asked), else Python. 0, or -1 when it failed. */
static int model(appell_loop *c, double t, const double *y, double *dy, double *lam)
{
    const double *bias = NULL;
    if (c->baumgarte) {
        c->residuals(t, y, y + c->nq, NULL, c->p, c->Fr, c->phi);
        for (int r = 0; r < c->s; ++r)
            c->bias[r] = 2.0 * c->alpha * nan0(c->phi[r]) + c->beta * c->beta * nan0(c->Fr[r]);
        bias = c->bias;
    }
    if (c->evaluate(t, y, c->p, bias, c->dep, c->cond_max, dy, lam) == 0 && !c->switched) return 0;
    if (!c->fallback) return -1;
    int r = c->fallback(t, y, dy, lam);
    if (r < 0) return -1;
    c->switched = r;
    return 0;
}

static int rhs(appell_loop *c, double t, const double *y, double *dy)
{
    c->nfev++;
    return model(c, t, y, dy, c->lamt);
}

static double rms_scaled(int ny, const double *x, const double *scale)
{
    double s = 0.0;
    for (int i = 0; i < ny; ++i) { double v = x[i] / scale[i]; s += v * v; }
    return sqrt(s / ny);
}

/* the initial step of Hairer, Norsett and Wanner (II.4), as SciPy's select_initial_step */
static int initial_step(appell_loop *c, double *h)
{
    int ny = c->ny;
    double *scale = c->dyt, *y1 = c->ytmp, *f1 = c->K + ny;
    double span = fabs(c->t_bound - c->t);
    if (ny == 0) { *h = INFINITY; return 0; }
    if (span == 0.0) { *h = 0.0; return 0; }
    for (int i = 0; i < ny; ++i) scale[i] = c->atol + fabs(c->y[i]) * c->rtol;
    double d0 = rms_scaled(ny, c->y, scale), d1 = rms_scaled(ny, c->f, scale);
    double h0 = (d0 < 1e-5 || d1 < 1e-5) ? 1e-6 : 0.01 * d0 / d1;
    if (h0 > span) h0 = span;
    for (int i = 0; i < ny; ++i) y1[i] = c->y[i] + h0 * c->f[i];
    if (rhs(c, c->t + h0, y1, f1)) return -1;
    double d2 = 0.0;
    for (int i = 0; i < ny; ++i) { double v = (f1[i] - c->f[i]) / scale[i]; d2 += v * v; }
    d2 = sqrt(d2 / ny) / h0;
    double h1 = (d1 <= 1e-15 && d2 <= 1e-15) ? fmax(1e-6, h0 * 1e-3) : pow(0.01 / fmax(d1, d2), 1.0 / 8.0);
    *h = fmin(fmin(100 * h0, h1), fmin(span, c->max_step));
    return 0;
}

/* start (or restart) at (t0, y0); first_step <= 0 selects it. 0, or -2 when the model failed */
int appell_loop_start(appell_loop *c, double t0, const double *y0, double t_bound, double rtol, double atol,
                      double max_step, double first_step)
{
    c->t = c->t_old = t0; c->t_bound = t_bound; c->rtol = rtol; c->atol = atol; c->max_step = max_step;
    c->h_prev = NAN; c->dense_ready = 0; c->have_prev = 0; c->prev_kept = 0;
    memcpy(c->y, y0, sizeof(double) * c->ny);
    if (rhs(c, t0, c->y, c->f)) return -2;
    if (c->blocks) {  /* a restart: its start may be the bottom of a dip (g0 above everything) */
        c->g0 = INFINITY;
        c->g1 = watch_measure(c, t0, c->y);
    }
    memcpy(c->lam, c->lamt, sizeof(double) * (c->s > 0 ? c->s : 1));
    if (first_step > 0.0) { c->h_abs = first_step; return 0; }
    return initial_step(c, &c->h_abs) ? -2 : 0;
}

void appell_loop_outputs(appell_loop *c, const double *t_eval, long n_eval, double *Y, double *A, double *L,
                         double *F, double *PHI)
{
    c->t_eval = t_eval; c->n_eval = n_eval;
    c->rec_y = Y; c->rec_acc = A; c->rec_lam = L; c->rec_F = F; c->rec_phi = PHI;
}

/* the last step becomes the previous one (its stages and interpolant kept for the watch) */
static void save_prev(appell_loop *c)
{
    int ny = c->ny;
    c->p_t_old = c->t_old; c->p_t = c->t; c->p_h = c->h_prev; c->prev_dense_ready = c->dense_ready;
    memcpy(c->p_y_old, c->y_old, sizeof(double) * ny);
    memcpy(c->p_y, c->y, sizeof(double) * ny);
    memcpy(c->p_f, c->f, sizeof(double) * ny);
    memcpy(c->p_K, c->K, sizeof(double) * NK * ny);
    memcpy(c->p_Fd, c->Fd, sizeof(double) * NF * ny);
    c->have_prev = 1;
}

/* one accepted step from (t, y); 0, -1 step size too small, -2 the model failed */
static int step(appell_loop *c)
{
    int ny = c->ny;
    double t = c->t, *y = c->y, *K = c->K, *yt = c->ytmp, *scale = c->dyt;
    double min_step = 10.0 * fabs(nextafter(t, INFINITY) - t);
    double h_abs = c->h_abs > c->max_step ? c->max_step : (c->h_abs < min_step ? min_step : c->h_abs);
    int rejected = 0;
    if (c->blocks && !isnan(c->h_prev)) save_prev(c);  /* the step that ends here becomes the previous one */
    else if (!c->prev_kept) c->have_prev = 0;
    c->prev_kept = 0;
    for (;;) {
        if (h_abs < min_step) return -1;
        double t_new = t + h_abs;
        if (t_new > c->t_bound) t_new = c->t_bound;
        double h = t_new - t;
        h_abs = fabs(h);
        memcpy(K, c->f, sizeof(double) * ny);
        for (int s = 1; s < NS; ++s) {
            for (int i = 0; i < ny; ++i) {
                double acc = 0.0;
                for (int j = 0; j < s; ++j) acc += K[j * ny + i] * A_[s][j];
                yt[i] = y[i] + acc * h;
            }
            if (rhs(c, t + C_[s] * h, yt, K + s * ny)) return -2;
        }
        double *y_new = c->y_old;            /* the new state is built in the old one's buffer */
        for (int i = 0; i < ny; ++i) {
            double acc = 0.0;
            for (int j = 0; j < NS; ++j) acc += K[j * ny + i] * B_[j];
            y_new[i] = y[i] + h * acc;
        }
        c->nfev++;
        if (model(c, t_new, y_new, K + NS * ny, c->lamt)) return -2;
        double e5 = 0.0, e3 = 0.0;
        for (int i = 0; i < ny; ++i) {
            double a5 = 0.0, a3 = 0.0;
            for (int j = 0; j <= NS; ++j) { a5 += K[j * ny + i] * E5_[j]; a3 += K[j * ny + i] * E3_[j]; }
            scale[i] = c->atol + max_nan(fabs(y[i]), fabs(y_new[i])) * c->rtol;
            a5 /= scale[i]; a3 /= scale[i];
            e5 += a5 * a5; e3 += a3 * a3;
        }
        double err = (e5 == 0.0 && e3 == 0.0) ? 0.0 : fabs(h) * e5 / sqrt((e5 + 0.01 * e3) * ny);
        if (err < 1.0) {
            double factor = err == 0.0 ? 10.0 : fmin(10.0, 0.9 * pow(err, -1.0 / 8.0));
            if (rejected && factor > 1.0) factor = 1.0;
            h_abs *= factor;
            /* accept: y_old <- y, y <- y_new (swap the buffers), f <- K[NS] */
            c->y_old = y; c->y = y_new;
            memcpy(c->f, K + NS * ny, sizeof(double) * ny);
            memcpy(c->lam, c->lamt, sizeof(double) * (c->s > 0 ? c->s : 1));
            c->t_old = t; c->t = t_new; c->h_prev = h; c->h_abs = h_abs;
            c->steps++; c->dense_ready = 0;
            return 0;
        }
        h_abs *= fmax(0.2, 0.9 * pow(err, -1.0 / 8.0));
        rejected = 1;
    }
}

/* the three extra stages and the coefficient vectors Fd of the interpolant of a step from
   (t_old, y_old) of size h to y_end with f_end there, stages K */
static int prepare(appell_loop *c, double t_old, double h, const double *y_old, const double *y_end,
                   const double *f_end, double *K, double *Fd)
{
    int ny = c->ny;
    double *yt = c->ytmp;
    for (int s = NS + 1; s < NK; ++s) {
        for (int i = 0; i < ny; ++i) {
            double acc = 0.0;
            for (int j = 0; j < s; ++j) acc += K[j * ny + i] * A_[s][j];
            yt[i] = y_old[i] + acc * h;
        }
        if (rhs(c, t_old + C_[s] * h, yt, K + s * ny)) return -2;
    }
    for (int i = 0; i < ny; ++i) {
        double dy = y_end[i] - y_old[i], f0 = K[i];
        Fd[i] = dy;
        Fd[ny + i] = h * f0 - dy;
        Fd[2 * ny + i] = 2.0 * dy - h * (f_end[i] + f0);
        for (int r = 0; r < NF - 3; ++r) {
            double acc = 0.0;
            for (int j = 0; j < NK; ++j) acc += D_[r][j] * K[j * ny + i];
            Fd[(3 + r) * ny + i] = h * acc;
        }
    }
    return 0;
}

/* the interpolant of the last step */
static int dense_prepare(appell_loop *c)
{
    if (c->dense_ready) return 0;
    if (prepare(c, c->t_old, c->h_prev, c->y_old, c->y, c->f, c->K, c->Fd)) return -2;
    c->dense_ready = 1;
    return 0;
}

static void interpolate_step(int ny, const double *Fd, const double *y_old, double t_old, double t_end, double t,
                             double *out)
{
    double x = (t - t_old) / (t_end - t_old), u = 1.0 - x;
    for (int i = 0; i < ny; ++i) {
        double v = Fd[6 * ny + i] * x;
        v = (v + Fd[5 * ny + i]) * u;
        v = (v + Fd[4 * ny + i]) * x;
        v = (v + Fd[3 * ny + i]) * u;
        v = (v + Fd[2 * ny + i]) * x;
        v = (v + Fd[ny + i]) * u;
        v = (v + Fd[i]) * x;
        out[i] = v + y_old[i];
    }
}

static void interpolate(const appell_loop *c, double t, double *out)
{
    interpolate_step(c->ny, c->Fd, c->y_old, c->t_old, c->t, t, out);
}

/* the previous step (the one before the last): 1 and its times in span[0..1], or 0 when
   there is none kept (the watch is off, or the last step is the first since a start) */
int appell_loop_previous(const appell_loop *c, double *span)
{
    if (!c->have_prev) return 0;
    span[0] = c->p_t_old; span[1] = c->p_t;
    return 1;
}

/* the states ys (m x ny) at the times ts of the previous step; 0, -1 none kept, -2 model failed */
int appell_loop_dense_previous(appell_loop *c, long m, const double *ts, double *ys)
{
    if (!c->have_prev) return -1;
    if (!c->prev_dense_ready) {
        if (prepare(c, c->p_t_old, c->p_h, c->p_y_old, c->p_y, c->p_f, c->p_K, c->p_Fd)) return -2;
        c->prev_dense_ready = 1;
    }
    for (long k = 0; k < m; ++k) interpolate_step(c->ny, c->p_Fd, c->p_y_old, c->p_t_old, c->p_t, ts[k], ys + k * c->ny);
    return 0;
}

/* the states ys (m x ny) at the times ts of the last step (Fortran's contd8); 0 or -2 */
int appell_loop_dense(appell_loop *c, long m, const double *ts, double *ys)
{
    if (dense_prepare(c)) return -2;
    for (long k = 0; k < m; ++k) interpolate(c, ts[k], ys + k * c->ny);
    return 0;
}

/* one output row k: accelerations (dy/dt's speed part), multipliers and residuals at (t, y) */
static int record_row(appell_loop *c, long k, double t, const double *y, const double *dy, const double *lam)
{
    int n = c->n, s = c->s, nq = c->nq;
    double *A = c->rec_acc + k * n, *L = c->rec_lam + k * s;
    if (dy == NULL) {
        if (model(c, t, y, c->dyt, c->lamt)) return -2;
        dy = c->dyt; lam = c->lamt;
    }
    for (int i = 0; i < n; ++i) A[i] = dy[nq + i];
    for (int r = 0; r < s; ++r) L[r] = lam[r];
    c->residuals(t, y, y + nq, NULL, c->p, c->rec_F + k * s, c->rec_phi + k * s);
    return 0;
}

/* the model at m given states: rows 0..m-1 of the output arrays (appell_loop_outputs); 0 or -2 */
int appell_loop_evaluate_many(appell_loop *c, long m, const double *ts, const double *ys)
{
    for (long k = 0; k < m; ++k) {
        memcpy(c->rec_y + k * c->ny, ys + k * c->ny, sizeof(double) * c->ny);
        if (record_row(c, k, ts[k], ys + k * c->ny, NULL, NULL)) return -2;
    }
    return 0;
}

/* the outputs k.. inside the last step (t_old, t]: the step's end exactly, else the dense output */
static int record_step(appell_loop *c, long *k)
{
    int ny = c->ny;
    while (*k < c->n_eval && c->t_eval[*k] <= c->t) {
        double tk = c->t_eval[*k], *yk = c->rec_y + *k * ny;
        if (tk == c->t) {
            memcpy(yk, c->y, sizeof(double) * ny);
            if (record_row(c, *k, tk, yk, c->f, c->lam)) return -2;
        } else {
            if (dense_prepare(c)) return -2;
            interpolate(c, tk, yk);
            if (record_row(c, *k, tk, yk, NULL, NULL)) return -2;
        }
        ++*k;
    }
    return 0;
}

/* the minimum-norm solution dx (in pz, m entries) of A dx = b for the rows x m matrix pA
   (row-major, rows <= m) and b in pb: Householder QR of A^T (the reflectors kept in the rows
   of pA, R_kj in row j), R^T u = b, dx = Q (u, 0). 0, or 1 where R's diagonal says that the
   rows are nearly dependent (header comment: Python projects) */
static int min_norm_step(appell_loop *c, int rows, int m)
{
    double *A = c->pA, *Rd = c->pRd, *tau = c->ptau, *z = c->pz, *b = c->pb, largest = 0.0;
    for (int k = 0; k < rows; ++k) {
        double *v = A + (size_t)k * m, norm = 0.0;
        for (int i = k; i < m; ++i) norm += v[i] * v[i];
        norm = sqrt(norm);
        if (!(norm > 0.0) || !isfinite(norm)) return 1;
        double alpha = v[k] >= 0.0 ? -norm : norm;
        v[k] -= alpha;
        tau[k] = 1.0 / (norm * (norm + fabs(v[k] + alpha)));  /* 2 / |v|^2 */
        Rd[k] = alpha;
        if (fabs(alpha) > largest) largest = fabs(alpha);
        for (int j = k + 1; j < rows; ++j) {
            double *a = A + (size_t)j * m, d = 0.0;
            for (int i = k; i < m; ++i) d += v[i] * a[i];
            d *= tau[k];
            for (int i = k; i < m; ++i) a[i] -= d * v[i];
        }
    }
    for (int k = 0; k < rows; ++k)
        if (!(fabs(Rd[k]) > PROJECTION_RANK * largest)) return 1;
    for (int j = 0; j < rows; ++j) {  /* R^T u = b, u in z */
        double acc = b[j];
        for (int k = 0; k < j; ++k) acc -= A[(size_t)j * m + k] * z[k];
        z[j] = acc / Rd[j];
    }
    for (int i = rows; i < m; ++i) z[i] = 0.0;
    for (int k = rows - 1; k >= 0; --k) {  /* z <- H_k z, the last reflector first */
        const double *v = A + (size_t)k * m;
        double d = 0.0;
        for (int i = k; i < m; ++i) d += v[i] * z[i];
        d *= tau[k];
        for (int i = k; i < m; ++i) z[i] -= d * v[i];
    }
    return 0;
}

/* y: y0 projected onto the constraints (header comment; the steps of
   appell.simulation.projection.project). 0, or 1 where Python should project */
static int project_state(appell_loop *c, double t, const double *y0, double *y)
{
    int nq = c->nq, n = c->n, s = c->s;
    memcpy(y, y0, sizeof(double) * c->ny);
    for (int level = 0; level < 2; ++level) {
        int m = level ? n : nq;
        double *x = level ? y + nq : y;
        const double *r = level ? c->pphi : c->pF;
        for (int it = 0; it < PROJECTION_ITER; ++it) {
            c->residuals(t, y, y + nq, NULL, c->p, c->pF, c->pphi);
            int rows = 0;
            double worst = 0.0;
            for (int i = 0; i < s; ++i) {
                if (isnan(r[i])) continue;
                if (!isfinite(r[i])) return 1;
                if (fabs(r[i]) > worst) worst = fabs(r[i]);
                c->prow[rows] = i; c->pb[rows] = -r[i]; ++rows;
            }
            if (rows == 0 || worst <= PROJECTION_TOL) break;
            if (rows > m) return 1;
            if (level) {  /* dphi/dw = J */
                c->pblocks(t, y, y + nq, NULL, c->p, c->pM, c->phQ, c->pJ, c->pc);
                for (int a = 0; a < rows; ++a) memcpy(c->pA + (size_t)a * m, c->pJ + (size_t)c->prow[a] * n, sizeof(double) * n);
            } else {  /* dF/dq by central differences */
                for (int j = 0; j < m; ++j) {
                    double xj = x[j], h = 1e-7 * fmax(1.0, fabs(xj));
                    x[j] = xj + h;
                    c->residuals(t, y, y + nq, NULL, c->p, c->pFp, c->pphi);
                    x[j] = xj - h;
                    c->residuals(t, y, y + nq, NULL, c->p, c->pFm, c->pphi);
                    x[j] = xj;
                    for (int a = 0; a < rows; ++a) {
                        double d = (c->pFp[c->prow[a]] - c->pFm[c->prow[a]]) / (2.0 * h);
                        c->pA[(size_t)a * m + j] = isnan(d) ? 0.0 : d;
                    }
                }
            }
            if (min_norm_step(c, rows, m)) return 1;
            double dmax = 0.0, xmax = 0.0;
            for (int j = 0; j < m; ++j) {
                x[j] += c->pz[j];
                if (fabs(c->pz[j]) > dmax) dmax = fabs(c->pz[j]);
                if (fabs(x[j]) > xmax) xmax = fabs(x[j]);
            }
            if (!isfinite(dmax) || !isfinite(xmax)) return 1;
            if (dmax <= 1e-15 * (1.0 + xmax)) break;
        }
        c->residuals(t, y, y + nq, NULL, c->p, c->pF, c->pphi);
        for (int i = 0; i < s; ++i)
            if (!isnan(r[i]) && !(fabs(r[i]) <= fmax(PROJECTION_TOL, PROJECTION_FAIL))) return 1;
    }
    return 0;
}

/* y0 (at t) projected onto the constraints into y as the loop does (the tests' entry):
   0, 1 where the loop leaves it to Python, -1 the projection is off */
int appell_loop_project(appell_loop *c, double t, const double *y0, double *y)
{
    if (!c->pblocks) return -1;
    return project_state(c, t, y0, y);
}

/* the projection of the last step's end in the loop (header comment): its outputs before
   the end from its dense output, the end projected, the restart there keeping the step size
   (as appell_loop_start with first_step), the end's output from the projected state.
   0 done, 1 Python should project (nothing changed), -2 the model failed */
static int project_step(appell_loop *c, long *k)
{
    int ny = c->ny;
    if (!c->pblocks || c->switched || project_state(c, c->t, c->y, c->pyp)) return 1;
    while (*k < c->n_eval && c->t_eval[*k] < c->t) {
        double tk = c->t_eval[*k], *yk = c->rec_y + *k * ny;
        if (dense_prepare(c)) return -2;
        interpolate(c, tk, yk);
        if (record_row(c, *k, tk, yk, NULL, NULL)) return -2;
        ++*k;
    }
    if (c->blocks) {  /* the step stays the watch's previous one across the restart */
        save_prev(c);
        c->prev_kept = 1;
    }
    memcpy(c->y, c->pyp, sizeof(double) * ny);
    if (rhs(c, c->t, c->y, c->f)) return -2;
    memcpy(c->lam, c->lamt, sizeof(double) * (c->s > 0 ? c->s : 1));
    c->t_old = c->t; c->h_prev = NAN; c->dense_ready = 0;
    if (c->h_abs > c->t_bound - c->t) c->h_abs = c->t_bound - c->t;
    c->projections++;
    if (*k < c->n_eval && c->t_eval[*k] == c->t) {
        double *yk = c->rec_y + *k * ny;
        memcpy(yk, c->y, sizeof(double) * ny);
        if (record_row(c, *k, c->t, yk, c->f, c->lam)) return -2;
        ++*k;
    }
    return 0;
}

/* steps until one needs Python: every step when single, else one that reaches t_bound, one
   after which the function evaluations exceed max_nfev (negative: no bound), one where the
   rank watch asks Python to look, or one whose end has a constraint residual above
   projection_tol that the loop cannot project itself (project_step). The outputs of the steps
   before it are recorded (rows *k.. of the output arrays, *k advanced); the returned step's
   are not. 1: a step was taken; -1: the step size fell below the spacing of floating-point
   numbers; -2: the model failed (Python holds the reason). */
int appell_loop_advance(appell_loop *c, int single, double projection_tol, long max_nfev, long *k)
{
    for (;;) {
        int r = step(c);
        if (r) return r;
        if (single || c->t >= c->t_bound) return 1;
        if (max_nfev >= 0 && c->nfev > max_nfev) return 1;
        if (c->blocks && c->s > 0 && watch_step(c)) return 1;
        if (projection_tol < INFINITY && c->s > 0) {
            double worst = 0.0;
            c->residuals(c->t, c->y, c->y + c->nq, NULL, c->p, c->Fr, c->phi);
            for (int i = 0; i < c->s; ++i) {
                if (fabs(c->Fr[i]) > worst) worst = fabs(c->Fr[i]);
                if (fabs(c->phi[i]) > worst) worst = fabs(c->phi[i]);
            }
            if (worst > projection_tol || isnan(worst)) {
                r = project_step(c, k);
                if (r) return r == 1 ? 1 : r;
                continue;
            }
        }
        if (record_step(c, k)) return -2;
    }
}

/* t, t_old, h_abs, h_previous, function evaluations, steps, then y */
void appell_loop_state(const appell_loop *c, double *out)
{
    out[0] = c->t; out[1] = c->t_old; out[2] = c->h_abs; out[3] = c->h_prev;
    out[4] = (double)c->nfev; out[5] = (double)c->steps;
    memcpy(out + 6, c->y, sizeof(double) * c->ny);
}
