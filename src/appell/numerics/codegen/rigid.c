
/* Rigid bodies on a joint tree (appell.numerics.rigid_tree has the same recursions in NumPy):
   spatial vectors [omega; v] in body axes; node b has parent PARENT[b] (-1: ground), speed k
   belongs to node NODE_OF[k]. appell_rigid_terms fills, per node, R (body -> parent, 9),
   r (3), c (6) and the inertia (m, com, Ixx Iyy Izz Ixy Ixz Iyz about the centre), per speed
   its column of S (6), the base's acceleration (6: -g where the tree carries gravity), and Q,
   J, c of the constraints. */

static void cross3(const double *a, const double *b, double *out)
{
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
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

/* h = I v about the body origin: n = Ic w + m c x (v + w x c), f = m (v + w x c) */
static void inertia_times(const double *in, const double *v, double *h)
{
    const double m = in[0], *c = in + 1;
    double wc[3], u[3], cu[3];
    cross3(v, c, wc);
    for (int i = 0; i < 3; ++i) u[i] = v[3 + i] + wc[i];
    cross3(c, u, cu);
    h[0] = in[4] * v[0] + in[7] * v[1] + in[8] * v[2] + m * cu[0];
    h[1] = in[7] * v[0] + in[5] * v[1] + in[9] * v[2] + m * cu[1];
    h[2] = in[8] * v[0] + in[9] * v[1] + in[6] * v[2] + m * cu[2];
    for (int i = 0; i < 3; ++i) h[3 + i] = m * u[i];
}

/* the bodies' forces f (6 NB) for speeds w, accelerations a and the base's acceleration base */
static void rigid_forces(const double *R, const double *r, const double *Sc, const double *cb, const double *in,
                         const double *w, const double *a, const double *base, double *f)
{
    double v[6 * NB], acc[6 * NB];
    for (int b = 0; b < NB; ++b) {
        double *vb = v + 6 * b, *ab = acc + 6 * b, vJ[6] = {0.0}, x[6];
        const int p = PARENT[b];
        if (p >= 0) {
            to_body(R + 9 * b, r + 3 * b, v + 6 * p, vb);
            to_body(R + 9 * b, r + 3 * b, acc + 6 * p, ab);
        } else {
            for (int i = 0; i < 6; ++i) vb[i] = 0.0;
            to_body(R + 9 * b, r + 3 * b, base, ab);
        }
        for (int k = 0; k < N; ++k) {
            if (NODE_OF[k] != b) continue;
            for (int i = 0; i < 6; ++i) { vJ[i] += Sc[6 * k + i] * w[k]; ab[i] += Sc[6 * k + i] * a[k]; }
        }
        for (int i = 0; i < 6; ++i) { vb[i] += vJ[i]; ab[i] += cb[6 * b + i]; }
        double t1[3], t2[3];                                 /* a += v x vJ (motion cross product) */
        cross3(vb, vJ, t1);
        for (int i = 0; i < 3; ++i) ab[i] += t1[i];
        cross3(vb, vJ + 3, t1);
        cross3(vb + 3, vJ, t2);
        for (int i = 0; i < 3; ++i) ab[3 + i] += t1[i] + t2[i];
        double h[6], *fb = f + 6 * b;                         /* f = I a + v x* I v */
        inertia_times(in + 10 * b, ab, fb);
        inertia_times(in + 10 * b, vb, h);
        cross3(vb, h, t1);
        cross3(vb + 3, h + 3, t2);
        cross3(vb, h + 3, x);
        for (int i = 0; i < 3; ++i) { fb[i] += t1[i] + t2[i]; fb[3 + i] += x[i]; }
    }
    for (int b = NB - 1; b >= 0; --b)
        if (PARENT[b] >= 0) add_to_parent(R + 9 * b, r + 3 * b, f + 6 * b, f + 6 * PARENT[b]);
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

/* 6x6 spatial inertia about the body origin: [[Ic + m cx cx^T, m cx], [m cx^T, m 1]] */
static void spatial_inertia(const double *in, double *I)
{
    const double m = in[0], cx = in[1], cy = in[2], cz = in[3];
    const double C[9] = {0.0, -cz, cy, cz, 0.0, -cx, -cy, cx, 0.0};
    const double Ic[9] = {in[4], in[7], in[8], in[7], in[5], in[9], in[8], in[9], in[6]};
    for (int i = 0; i < 36; ++i) I[i] = 0.0;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
            double s = 0.0;
            for (int k = 0; k < 3; ++k) s += C[3 * i + k] * C[3 * j + k];
            I[6 * i + j] = Ic[3 * i + j] + m * s;
            I[6 * i + 3 + j] = m * C[3 * i + j];
            I[6 * (3 + i) + j] = m * C[3 * j + i];
        }
    for (int i = 0; i < 3; ++i) I[6 * (3 + i) + 3 + i] = m;
}

/* X (6x6, parent -> body) = [[E, 0], [-E rx, E]], E = R^T */
static void transform(const double *R, const double *r, double *X)
{
    const double rx[9] = {0.0, -r[2], r[1], r[2], 0.0, -r[0], -r[1], r[0], 0.0};
    for (int i = 0; i < 36; ++i) X[i] = 0.0;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
            X[6 * i + j] = X[6 * (3 + i) + 3 + j] = R[3 * j + i];
            double s = 0.0;
            for (int k = 0; k < 3; ++k) s += R[3 * k + i] * rx[3 * k + j];
            X[6 * (3 + i) + j] = -s;
        }
}

/* M by composite inertias: I^c_p += X^T I^c X, then M_kl = S_l . (X^T ... I^c S_k) up the path */
static void rigid_mass(const double *R, const double *r, const double *Sc, const double *in, double *M)
{
    double Ic[36 * NB], X[36 * NB];
    for (int b = 0; b < NB; ++b) {
        spatial_inertia(in + 10 * b, Ic + 36 * b);
        transform(R + 9 * b, r + 3 * b, X + 36 * b);
    }
    for (int b = NB - 1; b >= 0; --b) {
        const int p = PARENT[b];
        if (p < 0) continue;
        const double *Xb = X + 36 * b, *I = Ic + 36 * b;
        double T[36];
        for (int i = 0; i < 6; ++i)
            for (int j = 0; j < 6; ++j) {
                double s = 0.0;
                for (int k = 0; k < 6; ++k) s += I[6 * i + k] * Xb[6 * k + j];
                T[6 * i + j] = s;
            }
        for (int i = 0; i < 6; ++i)
            for (int j = 0; j < 6; ++j) {
                double s = 0.0;
                for (int k = 0; k < 6; ++k) s += Xb[6 * k + i] * T[6 * k + j];
                Ic[36 * p + 6 * i + j] += s;
            }
    }
    for (int k = 0; k < N; ++k) {
        int j = NODE_OF[k];
        double F[6], G[6];
        for (int i = 0; i < 6; ++i) {
            double s = 0.0;
            for (int l = 0; l < 6; ++l) s += Ic[36 * j + 6 * i + l] * Sc[6 * k + l];
            F[i] = s;
        }
        while (j >= 0) {
            for (int l = 0; l < N; ++l) {
                if (NODE_OF[l] != j) continue;
                double s = 0.0;
                for (int i = 0; i < 6; ++i) s += Sc[6 * l + i] * F[i];
                M[k * N + l] = M[l * N + k] = s;
            }
            if (PARENT[j] >= 0) {
                const double *Xj = X + 36 * j;
                for (int i = 0; i < 6; ++i) {
                    double s = 0.0;
                    for (int l = 0; l < 6; ++l) s += Xj[6 * l + i] * F[l];
                    G[i] = s;
                }
                for (int i = 0; i < 6; ++i) F[i] = G[i];
            }
            j = PARENT[j];
        }
    }
}

/* M and h - Q from the joints' terms */
static void rigid_blocks(const double *R, const double *r, const double *Sc, const double *cb, const double *in,
                         const double *base, const double *Q, const double *w, double *M, double *hQ)
{
    double f[6 * NB];
    const double zero[N] = {0.0};
    rigid_forces(R, r, Sc, cb, in, w, zero, base, f);
    rigid_project(Sc, f, hQ);
    for (int k = 0; k < N; ++k) hQ[k] -= Q[k];
    for (int i = 0; i < N * N; ++i) M[i] = 0.0;
    rigid_mass(R, r, Sc, in, M);
}

/* the blocks M, h - Q, J, c of the dense route from the tree's recursions */
void appell_blocks(double t, const double *restrict q, const double *restrict w, const double *restrict a,
                   const double *restrict p, double *restrict M, double *restrict hQ, double *restrict J,
                   double *restrict c)
{
    double R[9 * NB], r[3 * NB], Sc[6 * N], cb[6 * NB], in[10 * NB], base[6], Q[N];
    appell_rigid_terms(t, q, w, a, p, R, r, Sc, cb, in, base, Q, J, c);
    rigid_blocks(R, r, Sc, cb, in, base, Q, w, M, hQ);
}

/* each node's reaction (F, M) in world axes about its joint point, from the joints' terms,
   gravity g, the joints' points o and the accelerations a */
static void rigid_wrenches(const double *R, const double *r, const double *Sc, const double *cb, const double *in,
                           const double *g, const double *o, const double *w, const double *a, double *out)
{
    double f[6 * NB], Rw[9 * NB];
    const double fall[6] = {0.0, 0.0, 0.0, -g[0], -g[1], -g[2]};
    rigid_forces(R, r, Sc, cb, in, w, a, fall, f);
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

/* every node's joint reaction (F, M), world axes, the moment about the joint's point: the inward
   forces with the base accelerating at -g and the accelerations a (out: 6 NB) */
void appell_wrenches(double t, const double *restrict q, const double *restrict w, const double *restrict a,
                     const double *restrict p, double *restrict out)
{
    double R[9 * NB], r[3 * NB], Sc[6 * N], cb[6 * NB], in[10 * NB], base[6], Q[N];
    double J[S * N > 0 ? S * N : 1], c[S > 0 ? S : 1], g[3], o[3 * NB];
    appell_rigid_terms(t, q, w, a, p, R, r, Sc, cb, in, base, Q, J, c);
    appell_rigid_points(t, q, w, a, p, g, o);
    rigid_wrenches(R, r, Sc, cb, in, g, o, w, a, out);
}
