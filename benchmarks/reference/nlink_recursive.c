/* O(n) reference: the n-link planar pendulum with its tip held on the vertical line x = d,
 * the same system, parameters and outputs as nlink.c, solved in O(n) instead of O(n^3).
 *
 * The links are massless rods joining point masses, so rod i carries only a tension T_i
 * along its unit vector e_i = (sin th_i, -cos th_i) (pulling mass i towards mass i-1).
 * With e_i' = (cos th_i, sin th_i), the acceleration of mass i (a_0 = 0, T_{n+1} = 0) is
 *
 *   a_i = (T_{i+1} e_{i+1} - T_i e_i) / m_i + (0, -g) + [i = n] lam (1, 0) / m_n,
 *
 * and the kinematics of rod i gives, along and across it,
 *
 *   e_i  . (a_i - a_{i-1}) = -l_i thd_i^2,        e_i' . (a_i - a_{i-1}) = l_i thdd_i.
 *
 * The tip stays on the line: x_tip'' = a_n . (1, 0) = 0, i.e. lam = T_n sin th_n. The first
 * set is then a tridiagonal system in T_1..T_n (weakly diagonally dominant: solved by the
 * Thomas algorithm without pivoting); the second gives each thdd_i from T_{i-1}, T_{i+1}.
 * With C_i = cos(th_i - th_{i-1}), row i reads
 *
 *   T_{i-1} C_i / m_{i-1} - T_i (1/m_i + 1/m_{i-1}) + T_{i+1} C_{i+1} / m_i = -l_i thd_i^2
 *
 * (row 1: no T_0 term, 1/m_0 = 0, and + g cos th_1 on the left; row n: 1/m_n becomes
 * cos^2 th_n / m_n once lam is eliminated). lam is the horizontal force of the line on the
 * tip, as in nlink.c. p = (m_1..m_n, l_1..l_n, g, d), y = (th_1..th_n, thd_1..thd_n).
 */
#include <math.h>

#define NMAX 1024

int nlink_recursive(int n, const double *y, const double *p, double *dy, double *lam)
{
    const double *th = y, *thd = y + n, *m = p, *l = p + n;
    const double g = p[2 * n];
    double s[NMAX], c[NMAX], lo[NMAX], di[NMAX], up[NMAX], r[NMAX], T[NMAX];
    if (n < 1 || n > NMAX) return -1;
    for (int i = 0; i < n; ++i) { s[i] = sin(th[i]); c[i] = cos(th[i]); }
    for (int i = 0; i < n; ++i) {
        double inv_prev = i ? 1.0 / m[i - 1] : 0.0;
        double own = (i == n - 1) ? c[i] * c[i] / m[i] : 1.0 / m[i];
        lo[i] = i ? (c[i] * c[i - 1] + s[i] * s[i - 1]) * inv_prev : 0.0;
        up[i] = i < n - 1 ? (c[i] * c[i + 1] + s[i] * s[i + 1]) / m[i] : 0.0;
        di[i] = -(own + inv_prev);
        r[i] = -l[i] * thd[i] * thd[i] - (i ? 0.0 : g * c[0]);
    }
    for (int i = 1; i < n; ++i) {             /* Thomas algorithm: forward sweep */
        double f = lo[i] / di[i - 1];
        di[i] -= f * up[i - 1];
        r[i] -= f * r[i - 1];
    }
    T[n - 1] = r[n - 1] / di[n - 1];
    for (int i = n - 2; i >= 0; --i) T[i] = (r[i] - up[i] * T[i + 1]) / di[i];
    *lam = T[n - 1] * s[n - 1];
    for (int i = 0; i < n; ++i) {
        /* l_i thdd_i = T_{i+1} sin(th_{i+1} - th_i)/m_i + T_{i-1} sin(th_{i-1} - th_i)/m_{i-1}
                        - [i = 1] g sin th_1 + [i = n] lam cos th_n / m_n */
        double acc = 0.0;
        if (i < n - 1) acc += T[i + 1] * (s[i + 1] * c[i] - c[i + 1] * s[i]) / m[i];
        if (i > 0) acc += T[i - 1] * (s[i - 1] * c[i] - c[i - 1] * s[i]) / m[i - 1];
        if (i == 0) acc -= g * s[0];
        if (i == n - 1) acc += *lam * c[i] / m[i];
        dy[i] = thd[i];
        dy[n + i] = acc / l[i];
    }
    return 0;
}
