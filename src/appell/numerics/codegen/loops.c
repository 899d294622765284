
/* Closed chains on a joint tree (appell.numerics.loops has the same in NumPy), after rigid.c.
   NC constraints: NL loop rows (LROW[i] their place among the constraints, LKIND[i] 0 for a
   point row e . (P_a - P_b) = 0, 1 for an alignment u . v = 0, 2 for a point row along e = Rw_a u
   fixed in body a (J gains (e x d)^T J_omega_a, c the terms of omega_a, alpha_a; the multiplier
   the moment e x d on body a, d = P_a - P_b), LBODY_A/LBODY_B their bodies,
   -1: ground) and S other rows (OROW[i] their place; J and c from appell_rigid_terms).
   appell_loop_data fills, per loop row, r_a, u_a, r_b, u_b (12) and the other rows' positions.
   Each body's world rotation Rw and origin pw, its spatial velocity v and acceleration at a = 0
   without gravity acc0 (body axes) come from one outward pass (rigid_forces with the base at -g,
   which also gives h; gravity taken back out: acc0 = acc + [0; Rw^T g]). A point P of body b has
   the Jacobian columns omega_k x (P - p_j) + v_k along its path; a row's column k is e . that,
   = S_k . [Rw_j^T ((P - p_j) x e); Rw_j^T e]. The split is solved on the tree's sparsity
   (loop_split_tree, where SPARSE_SPLIT): A = M + rho Jo^T Jo (rho the mean of M's diagonal, Jo
   the other rows alone, a free joint's unit quaternion: they lie on one path, so that A keeps M's
   branch-induced sparsity) factored A = L^T L without fill (Featherstone's LTL, RBDA 6.5, over the
   speeds in the tree's order, LAMBDA[g] the speed before g on its path); X = L^-T J^T (each row
   scattered up its paths only), u = -L^-T (h - Q); Cholesky of X^T X = J A^-1 J^T, mu from
   X^T X mu = -(X^T u + c), a = L^-1 (u + X mu), lambda = mu + rho c on the other rows. Where A is
   not positive definite there (a pivot below 1e-14 of the largest), the dense split: Cholesky of
   A = M + rho J^T J with every row, a0 = -A^-1 (h - Q), Y = A^-1 J^T, Cholesky of J Y,
   lambda = mu + rho c. Dependent or nearly dependent rows (a pivot of J A^-1 J^T below PIVOT_MIN
   of its largest diagonal entry) or a failed factorization report status 1: the NumPy route then
   decides the rank on the singular values of the mass-weighted rows (loops.RANK_TOLERANCE, 1e-5:
   1e-10 on this squared matrix) and names the undetermined combinations. PIVOT_MIN is far above
   that (a pivot is never below the smallest eigenvalue, but can be well above it), so that C
   never keeps a combination NumPy would drop; healthy loops have pivots of 0.1-0.4 (the biped,
   the gripper). */

#define PIVOT_MIN 1e-6

struct loop_state {
    double R[9 * NB], r[3 * NB], Sc[6 * N], cb[6 * NB], in[10 * NB], base[6], Q[N], Jo[DIM(S * N)], co[DIM(S)];
    double g[3], o[3 * NB], data[DIM(12 * NL)], phio[DIM(S)], Y[10 * NB];
    double Rw[9 * NB], pw[3 * NB], v[6 * NB], acc[6 * NB], f[6 * NB];
};

/* the joints' terms, the world poses, and (with velocities) v, acc0 and the bodies' forces f at a = 0 */
static void loop_state(double t, const double *q, const double *w, const double *u, const double *p,
                       struct loop_state *st, int velocities)
{
    appell_rigid_terms(t, q, w, u, p, st->R, st->r, st->Sc, st->cb, st->in, st->base, st->Q, st->Jo, st->co);
    appell_rigid_points(t, q, w, u, p, st->g, st->o);
    appell_loop_data(t, q, w, u, p, st->data, st->phio);
    for (int b = 0; b < NB; ++b) {
        const double *R = st->R + 9 * b, *r = st->r + 3 * b;
        double *Rw = st->Rw + 9 * b, *pw = st->pw + 3 * b;
        const int pa = PARENT[b];
        if (pa >= 0) {
            compose(st->Rw + 9 * pa, st->pw + 3 * pa, R, r, Rw, pw);
        } else {
            memcpy(Rw, R, 9 * sizeof(double));
            memcpy(pw, r, 3 * sizeof(double));
        }
    }
    if (!velocities) return;
    const double zero[N] = {0.0};
    for (int b = 0; b < NB; ++b) origin_inertia(st->in + 10 * b, st->Y + 10 * b);
    rigid_forces(st->R, st->r, st->Sc, st->cb, st->Y, w, zero, st->base, 0, PARENT, st->v, st->acc, st->f);
    for (int b = 0; b < NB; ++b) {
        const double *Rw = st->Rw + 9 * b;
        for (int i = 0; i < 3; ++i)
            st->acc[6 * b + 3 + i] += Rw[i] * st->g[0] + Rw[3 + i] * st->g[1] + Rw[6 + i] * st->g[2];
    }
}

/* y = Rw^T x */
static void to_axes(const double *Rw, const double *x, double *y)
{
    for (int i = 0; i < 3; ++i) y[i] = Rw[i] * x[0] + Rw[3 + i] * x[1] + Rw[6 + i] * x[2];
}

/* y = Rw x */
static void to_world(const double *Rw, const double *x, double *y)
{
    for (int i = 0; i < 3; ++i) y[i] = Rw[3 * i] * x[0] + Rw[3 * i + 1] * x[1] + Rw[3 * i + 2] * x[2];
}

/* row += scale e . (dP/dq columns) of the world point P of body b (point = 0: e . the angular
   velocity's columns) */
static void add_row(const struct loop_state *st, int b, const double *P, const double *e, double scale, int point,
                    double *row)
{
    for (int j = b; j >= 0; j = PARENT[j]) {
        if (FIRST[j] == FIRST[j + 1]) continue;
        const double *Rw = st->Rw + 9 * j, *pw = st->pw + 3 * j;
        double d[3], x[3], y1[3], y2[3] = {0.0, 0.0, 0.0};
        if (point) {
            for (int i = 0; i < 3; ++i) d[i] = P[i] - pw[i];
            cross3(d, e, x);
            to_axes(Rw, x, y1);
            to_axes(Rw, e, y2);
        } else {
            to_axes(Rw, e, y1);
        }
        for (int g = FIRST[j]; g < FIRST[j + 1]; ++g) {
            const int k = SPEEDS[g];
            const double *s = st->Sc + 6 * k;
            row[k] += scale * (s[0] * y1[0] + s[1] * y1[1] + s[2] * y1[2] + s[3] * y2[0] + s[4] * y2[1] + s[5] * y2[2]);
        }
    }
}

/* the world position P of the point r of body b, and (acc) its acceleration at a = 0 */
static void point_of(const struct loop_state *st, int b, const double *r, double *P, double *acc)
{
    if (b < 0) {
        for (int i = 0; i < 3; ++i) { P[i] = r[i]; if (acc) acc[i] = 0.0; }
        return;
    }
    const double *Rw = st->Rw + 9 * b;
    to_world(Rw, r, P);
    for (int i = 0; i < 3; ++i) P[i] += st->pw[3 * b + i];
    if (!acc) return;
    const double *v = st->v + 6 * b, *a0 = st->acc + 6 * b;
    double x[3], y[3], z[3], body[3];
    cross3(a0, r, x);                                   /* alpha x r */
    cross3(v, r, y);                                    /* omega x r */
    for (int i = 0; i < 3; ++i) y[i] += v[3 + i];
    cross3(v, y, z);                                    /* omega x (v_o + omega x r) */
    for (int i = 0; i < 3; ++i) body[i] = a0[3 + i] + x[i] + z[i];
    to_world(Rw, body, acc);
}

/* the world velocity R_b (v_o + omega x r) of the point r of body b (b >= 0) */
static void point_velocity(const struct loop_state *st, int b, const double *r, double *vel)
{
    const double *v = st->v + 6 * b;
    double x[3];
    cross3(v, r, x);
    for (int i = 0; i < 3; ++i) x[i] += v[3 + i];
    to_world(st->Rw + 9 * b, x, vel);
}

/* the loop rows: J (NC x N, rows LROW), c (bias) and Phi (positions), each where not NULL; with
   act, per row the force (3) and moment (3) on body a per unit multiplier (world axes; body b
   takes their opposites, the force alone for a row along body a's axis, LKIND 2) */
static void loop_rows(const struct loop_state *st, double *J, double *c, double *Phi, double *act)
{
    for (int i = 0; i < NL; ++i) {
        const double *d = st->data + 12 * i, *ra = d, *ua = d + 3, *rb = d + 6, *ub = d + 9;
        const int A = LBODY_A[i], B = LBODY_B[i], k = LROW[i];
        double *row = J ? J + N * k : 0, force[3] = {0.0, 0.0, 0.0}, moment[3] = {0.0, 0.0, 0.0};
        if (row) for (int j = 0; j < N; ++j) row[j] = 0.0;
        if (LKIND[i] != 1) {
            double Pa[3], Pb[3], aa[3], ab[3], e[3], dd[3];
            point_of(st, A, ra, Pa, c ? aa : 0);
            point_of(st, B, rb, Pb, c ? ab : 0);
            if (LKIND[i] == 2 && A >= 0) to_world(st->Rw + 9 * A, ua, e); else memcpy(e, ua, sizeof e);
            for (int j = 0; j < 3; ++j) dd[j] = Pa[j] - Pb[j];
            if (row && A >= 0) add_row(st, A, Pa, e, 1.0, 1, row);
            if (row && B >= 0) add_row(st, B, Pb, e, -1.0, 1, row);
            if (Phi) Phi[k] = e[0] * dd[0] + e[1] * dd[1] + e[2] * dd[2];
            if (c) c[k] = e[0] * (aa[0] - ab[0]) + e[1] * (aa[1] - ab[1]) + e[2] * (aa[2] - ab[2]);
            for (int j = 0; j < 3; ++j) force[j] = e[j];
            if (LKIND[i] == 2 && A >= 0) {                  /* e = R_a u turns with body a */
                cross3(e, dd, moment);                      /* e x d: J += (e x d)^T J_omega_a */
                if (row) add_row(st, A, 0, moment, 1.0, 0, row);
                if (c) {
                    double oa[3], la[3], oe[3], x[3], y[3], va[3], vb[3] = {0.0, 0.0, 0.0}, s = 0.0;
                    to_world(st->Rw + 9 * A, st->v + 6 * A, oa);
                    to_world(st->Rw + 9 * A, st->acc + 6 * A, la);
                    point_velocity(st, A, ra, va);
                    if (B >= 0) point_velocity(st, B, rb, vb);
                    cross3(oa, e, oe);                      /* omega_a x e */
                    cross3(la, e, x);                       /* alpha_a x e */
                    cross3(oa, oe, y);                      /* omega_a x (omega_a x e) */
                    for (int j = 0; j < 3; ++j) s += 2.0 * oe[j] * (va[j] - vb[j]) + (x[j] + y[j]) * dd[j];
                    c[k] += s;
                }
            }
        } else {
            double U[3], V[3], n[3], oa[3] = {0.0}, ob[3] = {0.0}, la[3] = {0.0}, lb[3] = {0.0};
            if (A >= 0) to_world(st->Rw + 9 * A, ua, U); else memcpy(U, ua, sizeof U);
            if (B >= 0) to_world(st->Rw + 9 * B, ub, V); else memcpy(V, ub, sizeof V);
            cross3(U, V, n);
            if (row && A >= 0) add_row(st, A, 0, n, 1.0, 0, row);
            if (row && B >= 0) add_row(st, B, 0, n, -1.0, 0, row);
            if (Phi) Phi[k] = U[0] * V[0] + U[1] * V[1] + U[2] * V[2];
            if (c) {
                if (A >= 0) { to_world(st->Rw + 9 * A, st->v + 6 * A, oa); to_world(st->Rw + 9 * A, st->acc + 6 * A, la); }
                if (B >= 0) { to_world(st->Rw + 9 * B, st->v + 6 * B, ob); to_world(st->Rw + 9 * B, st->acc + 6 * B, lb); }
                double x[3], y[3], z[3], s = 0.0;
                cross3(oa, U, x);
                cross3(x, V, y);                            /* (omega_a x u) x v */
                cross3(ob, V, x);
                cross3(U, x, z);                            /* u x (omega_b x v) */
                for (int j = 0; j < 3; ++j) s += n[j] * (la[j] - lb[j]) + (oa[j] - ob[j]) * (y[j] + z[j]);
                c[k] = s;
            }
            for (int j = 0; j < 3; ++j) moment[j] = n[j];
        }
        if (act) { memcpy(act + 6 * i, force, sizeof force); memcpy(act + 6 * i + 3, moment, sizeof moment); }
    }
    for (int i = 0; i < S; ++i) {
        const int k = OROW[i];
        if (J) memcpy(J + N * k, st->Jo + N * i, N * sizeof(double));
        if (c) c[k] = st->co[i];
        if (Phi) Phi[k] = st->phio[i];
    }
}

/* Cholesky factor (lower, in place) of the m x m matrix A; 1 where a pivot is not above
   tol times the largest diagonal entry */
static int cholesky(double *A, int m, double tol)
{
    double big = 0.0;
    for (int i = 0; i < m; ++i) if (A[i * m + i] > big) big = A[i * m + i];
    if (!(big > 0.0)) return m > 0;
    for (int j = 0; j < m; ++j) {
        double d = A[j * m + j];
        for (int k = 0; k < j; ++k) d -= A[j * m + k] * A[j * m + k];
        if (!(d > tol * big)) return 1;
        const double l = sqrt(d);
        A[j * m + j] = l;
        for (int i = j + 1; i < m; ++i) {
            double s = A[i * m + j];
            for (int k = 0; k < j; ++k) s -= A[i * m + k] * A[j * m + k];
            A[i * m + j] = s / l;
        }
    }
    return 0;
}

/* x = (L L^T)^-1 x */
static void cholesky_solve(const double *L, int m, double *x)
{
    for (int i = 0; i < m; ++i) {
        double s = x[i];
        for (int k = 0; k < i; ++k) s -= L[i * m + k] * x[k];
        x[i] = s / L[i * m + i];
    }
    for (int i = m - 1; i >= 0; --i) {
        double s = x[i];
        for (int k = i + 1; k < m; ++k) s -= L[k * m + i] * x[k];
        x[i] = s / L[i * m + i];
    }
}

/* the blocks M, h - Q, J, c (the constraints' order) */
static void loop_blocks(const struct loop_state *st, const double *w, double *M, double *hQ, double *J, double *c)
{
    rigid_project(st->Sc, st->f, hQ);
    for (int i = 0; i < N; ++i) hQ[i] -= st->Q[i];
    for (int i = 0; i < N * N; ++i) M[i] = 0.0;
    rigid_mass(st->R, st->r, st->Sc, st->Y, M);
    loop_rows(st, J, c, 0, 0);
    (void)w;
}

/* every joint's wrench (NB x 6, world axes, about the joint's point) at accelerations a with the
   loop forces of the multipliers lam at their anchors: the bodies' forces at a = 0 (st->f, the
   base at -g) plus those of the accelerations' own part, acc_b = X_b acc_parent + S_b a_b (linear
   in a: no velocity terms), f_b = Y_b acc_b, summed inward */
static void loop_wrenches(const struct loop_state *st, const double *w, const double *a, const double *lam,
                          double *out)
{
    double acc[6 * NB], f[6 * NB], ext[6 * NB] = {0.0}, act[DIM(6 * NL)];
    (void)w;
    for (int b = 0; b < NB; ++b) {
        double *ab = acc + 6 * b;
        if (PARENT[b] >= 0) to_body(st->R + 9 * b, st->r + 3 * b, acc + 6 * PARENT[b], ab);
        else for (int i = 0; i < 6; ++i) ab[i] = 0.0;
        for (int e = FIRST[b]; e < FIRST[b + 1]; ++e) {
            const int k = SPEEDS[e];
            for (int i = 0; i < 6; ++i) ab[i] += st->Sc[6 * k + i] * a[k];
        }
        inertia_times(st->Y + 10 * b, ab, f + 6 * b);
    }
    for (int b = NB - 1; b >= 0; --b)
        if (PARENT[b] >= 0) add_to_parent(st->R + 9 * b, st->r + 3 * b, f + 6 * b, f + 6 * PARENT[b]);
    for (int i = 0; i < 6 * NB; ++i) f[i] += st->f[i];
    loop_rows(st, 0, 0, 0, act);
    for (int i = 0; i < NL; ++i) {
        const double *d = st->data + 12 * i;
        const int body[2] = {LBODY_A[i], LBODY_B[i]};
        for (int side = 0; side < 2; ++side) {
            const int b = body[side];
            if (b < 0) continue;
            const double sgn = (side ? -1.0 : 1.0) * lam[LROW[i]], *r = d + 6 * side;
            double F[3], Mo[3], fb[3], mb[3], x[3];
            const double turn = side && LKIND[i] == 2 ? 0.0 : sgn;
            for (int j = 0; j < 3; ++j) { F[j] = sgn * act[6 * i + j]; Mo[j] = turn * act[6 * i + 3 + j]; }
            to_axes(st->Rw + 9 * b, F, fb);
            to_axes(st->Rw + 9 * b, Mo, mb);
            cross3(r, fb, x);
            for (int j = 0; j < 3; ++j) { ext[6 * b + 3 + j] += fb[j]; ext[6 * b + j] += mb[j] + x[j]; }
        }
    }
    for (int b = NB - 1; b >= 0; --b)
        if (PARENT[b] >= 0) add_to_parent(st->R + 9 * b, st->r + 3 * b, ext + 6 * b, ext + 6 * PARENT[b]);
    for (int i = 0; i < 6 * NB; ++i) f[i] -= ext[i];
    world_wrenches(st->R, st->o, f, out);
}

/* the split at the blocks: a, lam; 1 where it is not solved here (dependent rows) */
static int loop_split(double *M, const double *hQ, const double *J, const double *c, double *a, double *lam)
{
    double rho = 0.0, Yt[DIM(NC * N)], Z[DIM(NC * NC)], mu[DIM(NC)];
    for (int i = 0; i < N; ++i) rho += M[i * N + i];
    rho = NC > 0 ? rho / N : 0.0;
    for (int i = 0; i < N; ++i)
        for (int j = 0; j <= i; ++j) {
            double s = 0.0;
            for (int k = 0; k < NC; ++k) s += J[k * N + i] * J[k * N + j];
            M[i * N + j] += rho * s;
        }
    if (cholesky(M, N, 0.0)) return 1;
    for (int i = 0; i < N; ++i) a[i] = -hQ[i];
    cholesky_solve(M, N, a);
    if (NC == 0) return 0;
    for (int k = 0; k < NC; ++k) {
        memcpy(Yt + k * N, J + k * N, N * sizeof(double));
        cholesky_solve(M, N, Yt + k * N);
    }
    for (int i = 0; i < NC; ++i) {
        double s = c[i];
        for (int j = 0; j < N; ++j) s += J[i * N + j] * a[j];
        mu[i] = -s;
        for (int k = 0; k <= i; ++k) {
            double z = 0.0;
            for (int j = 0; j < N; ++j) z += J[i * N + j] * Yt[k * N + j];
            Z[i * NC + k] = Z[k * NC + i] = z;
        }
    }
    if (cholesky(Z, NC, PIVOT_MIN)) return 1;
    cholesky_solve(Z, NC, mu);
    for (int k = 0; k < NC; ++k) {
        for (int j = 0; j < N; ++j) a[j] += Yt[k * N + j] * mu[k];
        lam[k] = mu[k] + rho * c[k];
    }
    return 0;
}

#if SPARSE_SPLIT
/* the split on the tree's sparsity (the header): 0 solved, 1 dependent rows, 2 A not positive
   definite on the tree's pattern (the dense split then) */
static int loop_split_tree(const double *M, const double *hQ, const double *J, const double *c, double *a,
                           double *lam)
{
    double H[N * N], X[DIM(NC * N)], u[N], Z[DIM(NC * NC)], mu[DIM(NC)], rho = 0.0, big = 0.0;
    if (S > 0) {
        for (int i = 0; i < N; ++i) rho += M[i * N + i];
        rho /= N;
    }
    for (int g = 0; g < N; ++g) {                          /* A on each speed's path, the tree's order */
        const int k = SPEEDS[g];
        for (int h = g; h >= 0; h = LAMBDA[h]) {
            const int l = SPEEDS[h];
            double x = M[k * N + l];
            for (int i = 0; i < S; ++i) x += rho * J[OROW[i] * N + k] * J[OROW[i] * N + l];
            H[g * N + h] = x;
        }
        if (H[g * N + g] > big) big = H[g * N + g];
    }
    for (int k = N - 1; k >= 0; --k) {                     /* A = L^T L, L in H's lower part */
        const double d = H[k * N + k];
        if (!(d > 1e-14 * big)) return 2;
        const double l = sqrt(d);
        H[k * N + k] = l;
        for (int i = LAMBDA[k]; i >= 0; i = LAMBDA[i]) H[k * N + i] /= l;
        for (int i = LAMBDA[k]; i >= 0; i = LAMBDA[i])
            for (int j = i; j >= 0; j = LAMBDA[j]) H[i * N + j] -= H[k * N + i] * H[k * N + j];
    }
    for (int r = 0; r <= NC; ++r) {                        /* X = L^-T J^T, then u = -L^-T (h - Q) */
        double *x = r < NC ? X + r * N : u;
        for (int g = 0; g < N; ++g) x[g] = r < NC ? J[r * N + SPEEDS[g]] : -hQ[SPEEDS[g]];
        for (int i = N - 1; i >= 0; --i) {
            if (x[i] == 0.0) continue;
            x[i] /= H[i * N + i];
            for (int j = LAMBDA[i]; j >= 0; j = LAMBDA[j]) x[j] -= H[i * N + j] * x[i];
        }
    }
    for (int r = 0; r < NC; ++r) {
        double s = c[r];
        for (int g = 0; g < N; ++g) s += X[r * N + g] * u[g];
        mu[r] = -s;
        for (int k = 0; k <= r; ++k) {
            double z = 0.0;
            for (int g = 0; g < N; ++g) z += X[r * N + g] * X[k * N + g];
            Z[r * NC + k] = Z[k * NC + r] = z;
        }
    }
    if (cholesky(Z, NC, PIVOT_MIN)) return 1;
    cholesky_solve(Z, NC, mu);
    for (int r = 0; r < NC; ++r) {
        for (int g = 0; g < N; ++g) u[g] += X[r * N + g] * mu[r];
        lam[r] = mu[r];
    }
    for (int i = 0; i < S; ++i) lam[OROW[i]] += rho * c[OROW[i]];
    for (int g = 0; g < N; ++g) {                          /* a = L^-1 (u + X mu) */
        double x = u[g];
        for (int j = LAMBDA[g]; j >= 0; j = LAMBDA[j]) x -= H[g * N + j] * u[j];
        u[g] = x / H[g * N + g];
        a[SPEEDS[g]] = u[g];
    }
    return 0;
}
#endif

/* accelerations a, multipliers lam and every joint's wrench (out) at a state, u the controls;
   status[0] 0, or 1 where the split is left to the NumPy route */
void appell_loop_evaluate(double t, const double *restrict q, const double *restrict w, const double *restrict u,
                          const double *restrict p, double *restrict a, double *restrict lam, double *restrict out,
                          double *restrict status)
{
    struct loop_state st;
    double M[N * N], hQ[N], J[DIM(NC * N)], c[DIM(NC)];
    loop_state(t, q, w, u, p, &st, 1);
    loop_blocks(&st, w, M, hQ, J, c);
    int split = 2;
#if SPARSE_SPLIT
    if (NC > 0) split = loop_split_tree(M, hQ, J, c, a, lam);
#endif
    if (split == 2) split = loop_split(M, hQ, J, c, a, lam);
    status[0] = split;
    if (status[0] == 0) loop_wrenches(&st, w, a, lam, out);
}

/* M, h - Q, J, c at a state */
void appell_loop_blocks(double t, const double *restrict q, const double *restrict w, const double *restrict u,
                        const double *restrict p, double *restrict M, double *restrict hQ, double *restrict J,
                        double *restrict c)
{
    struct loop_state st;
    loop_state(t, q, w, u, p, &st, 1);
    loop_blocks(&st, w, M, hQ, J, c);
}

/* the constraints' positions Phi and J = dPhi/dq (w enters only the other rows' J: give zeros) */
void appell_loop_positions(double t, const double *restrict q, const double *restrict w, const double *restrict u,
                           const double *restrict p, double *restrict Phi, double *restrict J)
{
    struct loop_state st;
    loop_state(t, q, w, u, p, &st, 0);
    loop_rows(&st, J, 0, Phi, 0);
}

/* every joint's wrench at a state, alam = (a, lam) */
void appell_loop_wrenches(double t, const double *restrict q, const double *restrict w, const double *restrict u,
                          const double *restrict p, const double *restrict alam, double *restrict out)
{
    struct loop_state st;
    loop_state(t, q, w, u, p, &st, 1);
    loop_wrenches(&st, w, alam, alam + N, out);
}
