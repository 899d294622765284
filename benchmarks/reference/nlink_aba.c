/* Hand-written O(n) reference: n-link planar pendulum, tip held on the vertical line x = d
 * (the system of nlink.c), by the articulated-body recursion for point masses.
 *
 * Link i: u_i = l_i (cos th_i, sin th_i), bias acceleration c_i = l_i thd_i^2 (-sin th_i, cos th_i);
 * the tip moves with x'' = J a + c_x, J_i = l_i cos th_i. Inward pass: articulated inertias
 * I_i = m_i 1 + sum (I_c - I_c u_c u_c^T I_c / u_c^T I_c u_c) and bias forces (gravity, and the
 * unit horizontal tip force for the response Y = M^{-1} J^T); outward pass: accelerations.
 * lam = -(J a0 + c_x) / (J Y), a = a0 + lam Y. p = (m_1..m_n, l_1..l_n, g, d). */
#include <math.h>

#define NMAX 256

int nlink_aba_evaluate(int n, const double *y, const double *p, double *dy, double *lam)
{
    const double *th = y, *thd = y + n, *m = p, *l = p + n, g = p[2 * n];
    double ux[NMAX], uy[NMAX], cx[NMAX], cy[NMAX];
    double Ixx, Ixy, Iyy, Ivx[NMAX], Ivy[NMAX], Dinv[NMAX], r0[NMAX], r1[NMAX];
    double px0 = 0, py0 = 0, px1 = 0, py1 = 0;      /* bias forces: gravity + velocity; unit tip force */
    if (n > NMAX) return -1;
    for (int i = 0; i < n; ++i) {
        double s = sin(th[i]), c = cos(th[i]), w2 = thd[i] * thd[i] * l[i];
        ux[i] = l[i] * c; uy[i] = l[i] * s; cx[i] = -w2 * s; cy[i] = w2 * c;
    }
    Ixx = Ixy = Iyy = 0.0;
    px1 = -1.0;                                  /* f = I acc + p: the tip force enters as -e_x */
    for (int i = n - 1; i >= 0; --i) {
        Ixx += m[i]; Iyy += m[i];
        py0 += m[i] * g;                         /* gravity (0, -m g) enters as +m g */
        /* p += I c (bias acceleration of link i) for the gravity/velocity case */
        px0 += Ixx * cx[i] + Ixy * cy[i];
        py0 += Ixy * cx[i] + Iyy * cy[i];
        double ivx = Ixx * ux[i] + Ixy * uy[i], ivy = Ixy * ux[i] + Iyy * uy[i];
        double dinv = 1.0 / (ux[i] * ivx + uy[i] * ivy);
        Ivx[i] = ivx; Ivy[i] = ivy; Dinv[i] = dinv;
        r0[i] = -(ux[i] * px0 + uy[i] * py0);
        r1[i] = -(ux[i] * px1 + uy[i] * py1);
        px0 += ivx * dinv * r0[i]; py0 += ivy * dinv * r0[i];
        px1 += ivx * dinv * r1[i]; py1 += ivy * dinv * r1[i];
        Ixx -= ivx * ivx * dinv; Ixy -= ivx * ivy * dinv; Iyy -= ivy * ivy * dinv;
    }
    double ax0 = 0, ay0 = 0, ax1 = 0, ay1 = 0, Ja0 = 0, JY = 0, c_tip = 0;
    double *a0 = dy + n, Y[NMAX];
    for (int i = 0; i < n; ++i) {
        double k0 = Dinv[i] * (r0[i] - (Ivx[i] * ax0 + Ivy[i] * ay0));
        double k1 = Dinv[i] * (r1[i] - (Ivx[i] * ax1 + Ivy[i] * ay1));
        ax0 += ux[i] * k0 + cx[i]; ay0 += uy[i] * k0 + cy[i];
        ax1 += ux[i] * k1; ay1 += uy[i] * k1;
        a0[i] = k0; Y[i] = k1;
        Ja0 += ux[i] * k0; JY += ux[i] * k1; c_tip += cx[i];
    }
    double x = -(Ja0 + c_tip) / JY;
    for (int i = 0; i < n; ++i) { dy[i] = thd[i]; a0[i] += x * Y[i]; }
    *lam = x;
    return 0;
}
