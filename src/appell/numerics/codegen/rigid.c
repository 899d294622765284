
/* appell: loops over 3- and 6-vectors */
/* Rigid bodies on a joint tree (appell.numerics.rigid_tree has the same recursions in NumPy):
   spatial vectors [omega; v] in body axes; node b has parent PARENT[b] (-1: ground), speed k
   belongs to node NODE_OF[k]. appell_rigid_terms fills, per node, R (body -> parent, 9),
   r (3), c (6) and the inertia (m, com, Ixx Iyy Izz Ixy Ixz Iyz about the centre), per speed
   its column of S (6), the base's acceleration (6: -g where the tree carries gravity), and Q,
   J, c of the constraints. SPEEDS lists the speeds node by node, node b's from FIRST[b] to
   FIRST[b + 1]; RIGID[b] marks a subtree fixed rigidly to its parent (numerics.rigid_tree.
   rigid_subtrees), merged into it for M and h; FOLD[b] a node fixed rigidly to its parent whose
   subtree moves (a mount between two joints: numerics.rigid_tree.folded_nodes), merged likewise,
   its children then hanging from UP[b], the nearest ancestor that is not folded, through the
   composed transform. Inertias are kept about the body origin as (m, h = m c, I_o) and moved by
   3x3 algebra (Featherstone 2008, section 2.13). */

static void cross3(const double *a, const double *b, double *out)
{
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

/* the transform of a child (R2, r2) of a node (R1, r1) to that node's parent: R = R1 R2,
   r = r1 + R1 r2 */
static void compose(const double *R1, const double *r1, const double *R2, const double *r2, double *R, double *r)
{
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j)
            R[3 * i + j] = R1[3 * i] * R2[j] + R1[3 * i + 1] * R2[3 + j] + R1[3 * i + 2] * R2[6 + j];
        r[i] = r1[i] + R1[3 * i] * r2[0] + R1[3 * i + 1] * r2[1] + R1[3 * i + 2] * r2[2];
    }
}

/* x = X m: omega' = E omega, v' = E (v + omega x r), E = R^T */
static void to_body(const double *R, const double *r, const double *m, double *x)
{
    double t[3];
    cross3(m, r, t);
    for (int i = 0; i < 3; ++i) {
        x[i] = R[i] * m[0] + R[3 + i] * m[1] + R[6 + i] * m[2];
        x[3 + i] = R[i] * (m[3] + t[0]) + R[3 + i] * (m[4] + t[1]) + R[6 + i] * (m[5] + t[2]);
    }
}

/* f_p += X^T f: force E^T f_v, moment E^T n + r x (E^T f_v) */
static void add_to_parent(const double *R, const double *r, const double *f, double *fp)
{
    double n[3], fv[3], t[3];
    for (int i = 0; i < 3; ++i) {
        n[i] = R[3 * i] * f[0] + R[3 * i + 1] * f[1] + R[3 * i + 2] * f[2];
        fv[i] = R[3 * i] * f[3] + R[3 * i + 1] * f[4] + R[3 * i + 2] * f[5];
    }
    cross3(r, fv, t);
    for (int i = 0; i < 3; ++i) { fp[i] += n[i] + t[i]; fp[3 + i] += fv[i]; }
}

/* a body's inertia about its origin, body axes, as Y = (m, h = m c, I_o: xx yy zz xy xz yz) from
   (m, c, I about the centre): I_o = Ic + m (|c|^2 1 - c c^T) */
static void origin_inertia(const double *in, double *Y)
{
    const double m = in[0], cx = in[1], cy = in[2], cz = in[3];
    Y[0] = m; Y[1] = m * cx; Y[2] = m * cy; Y[3] = m * cz;
    Y[4] = in[4] + m * (cy * cy + cz * cz);
    Y[5] = in[5] + m * (cx * cx + cz * cz);
    Y[6] = in[6] + m * (cx * cx + cy * cy);
    Y[7] = in[7] - m * cx * cy;
    Y[8] = in[8] - m * cx * cz;
    Y[9] = in[9] - m * cy * cz;
}

/* Y_p += X^T Y X: the inertia moved to the parent's origin and axes (Featherstone 2008, 2.66):
   h' = R h + m r, I' = R I R^T + (2 (R h).r + m |r|^2) 1 - ((R h) r^T + r (R h)^T + m r r^T) */
static void add_inertia_to_parent(const double *R, const double *r, const double *Y, double *Yp)
{
    const double m = Y[0];
    const double I[9] = {Y[4], Y[7], Y[8], Y[7], Y[5], Y[9], Y[8], Y[9], Y[6]};
    double h[3], A[9];
    for (int i = 0; i < 3; ++i) {
        h[i] = R[3 * i] * Y[1] + R[3 * i + 1] * Y[2] + R[3 * i + 2] * Y[3];
        for (int j = 0; j < 3; ++j) A[3 * i + j] = R[3 * i] * I[j] + R[3 * i + 1] * I[3 + j] + R[3 * i + 2] * I[6 + j];
    }
    static const int row[6] = {0, 1, 2, 0, 0, 1}, col[6] = {0, 1, 2, 1, 2, 2};
    const double d = 2.0 * (h[0] * r[0] + h[1] * r[1] + h[2] * r[2]) + m * (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
    Yp[0] += m;
    for (int i = 0; i < 3; ++i) Yp[1 + i] += h[i] + m * r[i];
    for (int e = 0; e < 6; ++e) {
        const int i = row[e], j = col[e];
        const double rot = A[3 * i] * R[3 * j] + A[3 * i + 1] * R[3 * j + 1] + A[3 * i + 2] * R[3 * j + 2];
        Yp[4 + e] += rot + (i == j ? d : 0.0) - (h[i] * r[j] + r[i] * h[j] + m * r[i] * r[j]);
    }
}

/* F = Y v about the body origin: n = I_o w + h x v, f = m v - h x w */
static void inertia_times(const double *Y, const double *v, double *F)
{
    const double m = Y[0], *h = Y + 1;
    double hv[3], hw[3];
    cross3(h, v + 3, hv);
    cross3(h, v, hw);
    F[0] = Y[4] * v[0] + Y[7] * v[1] + Y[8] * v[2] + hv[0];
    F[1] = Y[7] * v[0] + Y[5] * v[1] + Y[9] * v[2] + hv[1];
    F[2] = Y[8] * v[0] + Y[9] * v[1] + Y[6] * v[2] + hv[2];
    for (int i = 0; i < 3; ++i) F[3 + i] = m * v[3 + i] - hw[i];
}

/* f = Y a + v x* (Y v): the force of a body of inertia Y moving with v and accelerating at a */
static void body_force(const double *Y, const double *v, const double *a, double *f)
{
    double h[6], t1[3], t2[3], x[3];
    inertia_times(Y, a, f);
    inertia_times(Y, v, h);
    cross3(v, h, t1);
    cross3(v + 3, h + 3, t2);
    cross3(v, h + 3, x);
    for (int i = 0; i < 3; ++i) { f[i] += t1[i] + t2[i]; f[3 + i] += x[i]; }
}

/* the bodies' forces f (6 NB), velocities v and accelerations acc for speeds w, accelerations a
   and the base's acceleration base, with the inertias Y (origin_inertia), each node b hanging
   from up[b] through (R, r); nodes with skip[b] (0: none) are left out */
static void rigid_forces(const double *R, const double *r, const double *Sc, const double *cb, const double *Y,
                         const double *w, const double *a, const double *base, const unsigned char *skip,
                         const int *up, double *v, double *acc, double *f)
{
    for (int b = 0; b < NB; ++b) {
        if (skip && skip[b]) continue;
        double *vb = v + 6 * b, *ab = acc + 6 * b, vJ[6] = {0.0};
        const int p = up[b];
        if (p >= 0) {
            to_body(R + 9 * b, r + 3 * b, v + 6 * p, vb);
            to_body(R + 9 * b, r + 3 * b, acc + 6 * p, ab);
        } else {
            for (int i = 0; i < 6; ++i) vb[i] = 0.0;
            to_body(R + 9 * b, r + 3 * b, base, ab);
        }
        for (int e = FIRST[b]; e < FIRST[b + 1]; ++e) {
            const int k = SPEEDS[e];
            for (int i = 0; i < 6; ++i) { vJ[i] += Sc[6 * k + i] * w[k]; ab[i] += Sc[6 * k + i] * a[k]; }
        }
        for (int i = 0; i < 6; ++i) { vb[i] += vJ[i]; ab[i] += cb[6 * b + i]; }
        double t1[3], t2[3];                                 /* a += v x vJ (motion cross product) */
        cross3(vb, vJ, t1);
        for (int i = 0; i < 3; ++i) ab[i] += t1[i];
        cross3(vb, vJ + 3, t1);
        cross3(vb + 3, vJ, t2);
        for (int i = 0; i < 3; ++i) ab[3 + i] += t1[i] + t2[i];
        body_force(Y + 10 * b, vb, ab, f + 6 * b);
    }
    for (int b = NB - 1; b >= 0; --b)
        if (up[b] >= 0 && !(skip && skip[b])) add_to_parent(R + 9 * b, r + 3 * b, f + 6 * b, f + 6 * up[b]);
}

/* tau = S^T f, the generalized forces of the bodies' forces */
static void rigid_project(const double *Sc, const double *f, double *tau)
{
    for (int k = 0; k < N; ++k) {
        const double *fb = f + 6 * NODE_OF[k];
        double s = 0.0;
        for (int i = 0; i < 6; ++i) s += Sc[6 * k + i] * fb[i];
        tau[k] = s;
    }
}

/* What depends on the parameters alone: the inertias about the body origins with each subtree
   fixed rigidly to its parent merged into the nearest moving body (Ym: RIGID[b], no speeds, no
   motion in it; Pinocchio merges fixed joints alike) and with the folded nodes merged as well
   (Ye: FOLD[b]), and each folded node's transform to UP[b] (Rf, rf) */
struct rigid_constants { double Ym[10 * NB], Ye[10 * NB], Rf[9 * NB], rf[3 * NB]; };

/* node b's transform to UP[b] (Ro, ro): through its folded parent's (Rf, rf), else its own */
static void to_up(const double *R, const double *r, const double *Rf, const double *rf, int b, double *Ro, double *ro)
{
    const int p = PARENT[b];
    if (p >= 0 && FOLD[p]) {
        compose(Rf + 9 * p, rf + 3 * p, R + 9 * b, r + 3 * b, Ro, ro);
    } else {
        memcpy(Ro, R + 9 * b, 9 * sizeof(double));
        memcpy(ro, r + 3 * b, 3 * sizeof(double));
    }
}

static void rigid_constants(const double *R, const double *r, const double *in, struct rigid_constants *k)
{
    for (int b = 0; b < NB; ++b) origin_inertia(in + 10 * b, k->Ym + 10 * b);
    for (int b = NB - 1; b >= 0; --b)
        if (RIGID[b] && PARENT[b] >= 0) add_inertia_to_parent(R + 9 * b, r + 3 * b, k->Ym + 10 * b, k->Ym + 10 * PARENT[b]);
    for (int i = 0; i < 10 * NB; ++i) k->Ye[i] = k->Ym[i];
    for (int b = NB - 1; b >= 0; --b)
        if (FOLD[b]) add_inertia_to_parent(R + 9 * b, r + 3 * b, k->Ye + 10 * b, k->Ye + 10 * PARENT[b]);
    for (int b = 0; b < NB; ++b)
        if (FOLD[b]) to_up(R, r, k->Rf, k->rf, b, k->Rf + 9 * b, k->rf + 3 * b);
}

/* the constants for the parameters p, computed once per parameter set where they are constants
   (CONSTANT_INERTIA: the generated terms say so), else every time, into the caller's k */
static const struct rigid_constants *rigid_constants_at(const double *p, const double *R, const double *r,
                                                        const double *in, struct rigid_constants *k)
{
#if CONSTANT_INERTIA
    static _Thread_local struct rigid_constants cache;
    static _Thread_local double key[DIM(NP)];
    static _Thread_local int valid = 0;
    if (valid && (NP == 0 || memcmp(key, p, NP * sizeof(double)) == 0)) return &cache;
    rigid_constants(R, r, in, &cache);
    if (NP > 0) memcpy(key, p, NP * sizeof(double));
    valid = 1;
    (void)k;
    return &cache;
#else
    (void)p;
    rigid_constants(R, r, in, k);
    return k;
#endif
}

/* each moving node's transform to UP[b] (Re, re): a folded parent's composed in */
static void hanging(const double *R, const double *r, const struct rigid_constants *k, double *Re, double *re)
{
    for (int b = 0; b < NB; ++b)
        if (!SKIP[b]) to_up(R, r, k->Rf, k->rf, b, Re + 9 * b, re + 3 * b);
}

/* M by composite inertias (CRBA): Y^c_p += X^T Y^c X inward, then M_kl = S_l . (X^T ... Y^c S_k)
   along the path to the root; the moving nodes only, each hanging from UP[b] through (R, r)
   (hanging), with the inertias Ye (rigid_constants) */
static void rigid_mass(const double *R, const double *r, const double *Sc, const double *Ye, double *M)
{
    double Yc[10 * NB];
    for (int b = 0; b < NB; ++b)
        if (!SKIP[b]) for (int i = 0; i < 10; ++i) Yc[10 * b + i] = Ye[10 * b + i];
    for (int b = NB - 1; b >= 0; --b)
        if (!SKIP[b] && UP[b] >= 0) add_inertia_to_parent(R + 9 * b, r + 3 * b, Yc + 10 * b, Yc + 10 * UP[b]);
    for (int e = 0; e < N; ++e) {
        const int k = SPEEDS[e];
        int j = NODE_OF[k];
        double F[6];
        inertia_times(Yc + 10 * j, Sc + 6 * k, F);
        while (j >= 0) {
            for (int g = FIRST[j]; g < FIRST[j + 1]; ++g) {
                const int l = SPEEDS[g];
                double s = 0.0;
                for (int i = 0; i < 6; ++i) s += Sc[6 * l + i] * F[i];
                M[k * N + l] = M[l * N + k] = s;
            }
            if (UP[j] >= 0) {
                double G[6] = {0.0};
                add_to_parent(R + 9 * j, r + 3 * j, F, G);
                for (int i = 0; i < 6; ++i) F[i] = G[i];
            }
            j = UP[j];
        }
    }
}

/* M and h - Q from the joints' terms; v, acc and f of the moving nodes (neither RIGID nor
   FOLD) at a = 0, with (Re, re) from hanging */
static void rigid_blocks(const double *Re, const double *re, const double *Sc, const double *cb,
                         const struct rigid_constants *k, const double *base, const double *Q, const double *w,
                         double *M, double *hQ, double *v, double *acc, double *f)
{
    const double zero[N] = {0.0};
    rigid_forces(Re, re, Sc, cb, k->Ye, w, zero, base, SKIP, UP, v, acc, f);
    rigid_project(Sc, f, hQ);
    for (int i = 0; i < N; ++i) hQ[i] -= Q[i];
    for (int i = 0; i < N * N; ++i) M[i] = 0.0;
    rigid_mass(Re, re, Sc, k->Ye, M);
}

/* the blocks M, h - Q, J, c of the dense route from the tree's recursions */
void appell_blocks(double t, const double *restrict q, const double *restrict w, const double *restrict a,
                   const double *restrict p, double *restrict M, double *restrict hQ, double *restrict J,
                   double *restrict c)
{
    double R[9 * NB], r[3 * NB], Sc[6 * N], cb[6 * NB], in[10 * NB], base[6], Q[N], Re[9 * NB], re[3 * NB];
    double v[6 * NB], acc[6 * NB], f[6 * NB];
    struct rigid_constants own;
    appell_rigid_terms(t, q, w, a, p, R, r, Sc, cb, in, base, Q, J, c);
    const struct rigid_constants *k = rigid_constants_at(p, R, r, in, &own);
    hanging(R, r, k, Re, re);
    rigid_blocks(Re, re, Sc, cb, k, base, Q, w, M, hQ, v, acc, f);
}

/* each node's reaction (F, M) in world axes about its joint point (o) from its inward force f
   (body axes, about the body origin) */
static void world_wrenches(const double *R, const double *o, const double *f, double *out)
{
    double Rw[9 * NB];
    for (int b = 0; b < NB; ++b) {
        double *Rb = Rw + 9 * b, m[3], tmp[3];
        const double *fb = f + 6 * b, *Rr = R + 9 * b;
        if (PARENT[b] >= 0) {
            const double *Rp = Rw + 9 * PARENT[b];
            for (int i = 0; i < 3; ++i)
                for (int j = 0; j < 3; ++j)
                    Rb[3 * i + j] = Rp[3 * i] * Rr[j] + Rp[3 * i + 1] * Rr[3 + j] + Rp[3 * i + 2] * Rr[6 + j];
        } else {
            for (int i = 0; i < 9; ++i) Rb[i] = Rr[i];
        }
        cross3(o + 3 * b, fb + 3, tmp);
        for (int i = 0; i < 3; ++i) m[i] = fb[i] - tmp[i];
        for (int i = 0; i < 3; ++i) {
            out[6 * b + i] = Rb[3 * i] * fb[3] + Rb[3 * i + 1] * fb[4] + Rb[3 * i + 2] * fb[5];
            out[6 * b + 3 + i] = Rb[3 * i] * m[0] + Rb[3 * i + 1] * m[1] + Rb[3 * i + 2] * m[2];
        }
    }
}

/* each node's reaction from the joints' terms, gravity g, the joints' points o and the
   accelerations a: one RNEA pass over every node with its own inertia Y */
static void rigid_wrenches(const double *R, const double *r, const double *Sc, const double *cb, const double *Y,
                           const double *g, const double *o, const double *w, const double *a, double *out)
{
    double f[6 * NB], v[6 * NB], acc[6 * NB];
    const double fall[6] = {0.0, 0.0, 0.0, -g[0], -g[1], -g[2]};
    rigid_forces(R, r, Sc, cb, Y, w, a, fall, 0, PARENT, v, acc, f);
    world_wrenches(R, o, f, out);
}

/* the same reactions from the pass of rigid_blocks at a = 0 (v, acc, f on the moving nodes,
   with the base at base), by linearity in a and in the base's acceleration: a second, shorter
   pass over the moving nodes adds the part of the accelerations a and of the base's change to
   -g (no velocity terms); then each RIGID node's force is that of its rigid subtree,
   f = Ym a + v x* Ym v, moving with it, and each FOLD node's that of its own rigid subtree plus
   what its moving children pass to it */
static void rigid_wrenches_after(const double *R, const double *r, const double *Re, const double *re,
                                 const double *Sc, const struct rigid_constants *k, const double *g, const double *o,
                                 const double *base, const double *a, double *v, double *acc, double *f, double *out)
{
    double da[6 * NB], df[6 * NB], rest[6];
    const double fall[6] = {0.0, 0.0, 0.0, -g[0], -g[1], -g[2]}, still[6] = {0.0};
    for (int i = 0; i < 6; ++i) rest[i] = fall[i] - base[i];
    for (int b = 0; b < NB; ++b) {
        double *ab = da + 6 * b;
        if (SKIP[b]) continue;
        to_body(Re + 9 * b, re + 3 * b, UP[b] >= 0 ? da + 6 * UP[b] : rest, ab);
        for (int e = FIRST[b]; e < FIRST[b + 1]; ++e)
            for (int i = 0; i < 6; ++i) ab[i] += Sc[6 * SPEEDS[e] + i] * a[SPEEDS[e]];
        inertia_times(k->Ye + 10 * b, ab, df + 6 * b);
    }
    for (int b = NB - 1; b >= 0; --b) {
        if (SKIP[b]) continue;
        if (UP[b] >= 0) add_to_parent(Re + 9 * b, re + 3 * b, df + 6 * b, df + 6 * UP[b]);
        for (int i = 0; i < 6; ++i) { f[6 * b + i] += df[6 * b + i]; acc[6 * b + i] += da[6 * b + i]; }
    }
    for (int b = 0; b < NB; ++b) {
        if (!SKIP[b]) continue;
        double *vb = v + 6 * b, *ab = acc + 6 * b;
        const int p = PARENT[b];
        to_body(R + 9 * b, r + 3 * b, p >= 0 ? v + 6 * p : still, vb);
        to_body(R + 9 * b, r + 3 * b, p >= 0 ? acc + 6 * p : fall, ab);
        body_force(k->Ym + 10 * b, vb, ab, f + 6 * b);
    }
    for (int b = NB - 1; b >= 0; --b) {
        const int p = PARENT[b];
        if (p >= 0 && FOLD[p] && !RIGID[b]) add_to_parent(R + 9 * b, r + 3 * b, f + 6 * b, f + 6 * p);
    }
    world_wrenches(R, o, f, out);
}

/* every node's joint reaction (F, M), world axes, the moment about the joint's point: the inward
   forces with the base accelerating at -g and the accelerations a (out: 6 NB) */
void appell_wrenches(double t, const double *restrict q, const double *restrict w, const double *restrict a,
                     const double *restrict p, double *restrict out)
{
    double R[9 * NB], r[3 * NB], Sc[6 * N], cb[6 * NB], in[10 * NB], base[6], Q[N];
    double J[S * N > 0 ? S * N : 1], c[S > 0 ? S : 1], g[3], o[3 * NB], Y[10 * NB];
    appell_rigid_terms(t, q, w, a, p, R, r, Sc, cb, in, base, Q, J, c);
    appell_rigid_points(t, q, w, a, p, g, o);
    for (int b = 0; b < NB; ++b) origin_inertia(in + 10 * b, Y + 10 * b);
    rigid_wrenches(R, r, Sc, cb, Y, g, o, w, a, out);
}
