/* Hand-written reference: n-link planar pendulum, tip held on the vertical line x = d.
 *
 * Point mass m_i at the outer end of link i (length l_i); theta_i is the absolute angle
 * of link i from the downward vertical. p = (m_1..m_n, l_1..l_n, g, d),
 * y = (theta_1..theta_n, thetadot_1..thetadot_n). With mu_ij = sum_{k >= max(i,j)} m_k:
 *
 *   M_ij = mu_ij l_i l_j cos(th_i - th_j)
 *   h_i  = sum_j mu_ij l_i l_j sin(th_i - th_j) thd_j^2
 *   Q_i  = -g mu_ii l_i sin(th_i)
 *   J_i  = l_i cos(th_i),   c = -sum_i l_i sin(th_i) thd_i^2    (tip: x_tip'' = J a + c)
 *
 * and [M  -J^T; J  0] [a; lam] = [Q - h; -c] is solved by Gaussian elimination with
 * partial pivoting. lam is the horizontal force of the line on the tip.
 */
#include <math.h>

#define NMAX 64

int nlink_evaluate(int n, const double *y, const double *p, double *dy, double *lam)
{
    const double *th = y, *thd = y + n, *m = p, *l = p + n;
    const double g = p[2 * n];
    double s[NMAX], c[NMAX], mu[NMAX + 1], A[(NMAX + 1) * (NMAX + 2)];
    const int k = n + 1, w = n + 2;           /* augmented system size and row width */
    if (n > NMAX) return -1;
    mu[n] = 0.0;
    for (int i = n - 1; i >= 0; --i) mu[i] = mu[i + 1] + m[i];
    for (int i = 0; i < n; ++i) { s[i] = sin(th[i]); c[i] = cos(th[i]); }
    double bias = 0.0;
    for (int i = 0; i < n; ++i) {
        double h = 0.0;
        for (int j = 0; j < n; ++j) {
            double ll = mu[i > j ? i : j] * l[i] * l[j];
            A[i * w + j] = ll * (c[i] * c[j] + s[i] * s[j]);
            h += ll * (s[i] * c[j] - c[i] * s[j]) * thd[j] * thd[j];
        }
        A[i * w + n] = -l[i] * c[i];          /* -J^T */
        A[n * w + i] = l[i] * c[i];           /*  J   */
        A[i * w + k] = -g * mu[i] * l[i] * s[i] - h;
        bias -= l[i] * s[i] * thd[i] * thd[i];
    }
    A[n * w + n] = 0.0;
    A[n * w + k] = -bias;
    for (int col = 0; col < k; ++col) {       /* forward elimination */
        int r = col;
        for (int i = col + 1; i < k; ++i) if (fabs(A[i * w + col]) > fabs(A[r * w + col])) r = i;
        if (A[r * w + col] == 0.0) return 1;
        if (r != col) for (int j = col; j < w; ++j) { double x = A[col * w + j]; A[col * w + j] = A[r * w + j]; A[r * w + j] = x; }
        for (int i = col + 1; i < k; ++i) {
            double f = A[i * w + col] / A[col * w + col];
            for (int j = col; j < w; ++j) A[i * w + j] -= f * A[col * w + j];
        }
    }
    for (int i = k - 1; i >= 0; --i) {        /* back substitution */
        double x = A[i * w + k];
        for (int j = i + 1; j < k; ++j) x -= A[i * w + j] * A[j * w + k];
        A[i * w + k] = x / A[i * w + i];
    }
    for (int i = 0; i < n; ++i) { dy[i] = thd[i]; dy[n + i] = A[i * w + k]; }
    *lam = A[n * w + k];
    return 0;
}
