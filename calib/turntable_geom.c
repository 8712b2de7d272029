/* turntable_geom.c - small geometry of turntable.h: symmetric 3x3 eigenvectors, plane
 * fit, Rodrigues rotation, a dense linear solve and a circle fit. */
#include <errno.h>
#include <math.h>
#include <string.h>

#include "calib/turntable.h"
#include "calib/turntable_geom.h"

void cal_eig3(const double A[9], double w[3], double V[9])
{
        double a[9];

        memcpy(a, A, sizeof(a));
        memset(V, 0, 9 * sizeof(double));
        V[0] = V[4] = V[8] = 1;
        for (int sweep = 0; sweep < 50; sweep++) {
                double off = a[1] * a[1] + a[2] * a[2] + a[5] * a[5];
                if (off < 1e-30 * (a[0] * a[0] + a[4] * a[4] + a[8] * a[8]) + 1e-300)
                        break;
                for (int p = 0; p < 2; p++)
                        for (int q = p + 1; q < 3; q++) {
                                double apq = a[p * 3 + q];
                                if (apq == 0)
                                        continue;
                                double th = (a[q * 3 + q] - a[p * 3 + p]) / (2 * apq);
                                double t = (th >= 0 ? 1 : -1) / (fabs(th) + sqrt(th * th + 1));
                                double c = 1 / sqrt(t * t + 1), s = t * c;
                                for (int k = 0; k < 3; k++) { /* a = J^T a J */
                                        double x = a[k * 3 + p], y = a[k * 3 + q];
                                        a[k * 3 + p] = c * x - s * y;
                                        a[k * 3 + q] = s * x + c * y;
                                }
                                for (int k = 0; k < 3; k++) {
                                        double x = a[p * 3 + k], y = a[q * 3 + k];
                                        a[p * 3 + k] = c * x - s * y;
                                        a[q * 3 + k] = s * x + c * y;
                                }
                                for (int k = 0; k < 3; k++) {
                                        double x = V[k * 3 + p], y = V[k * 3 + q];
                                        V[k * 3 + p] = c * x - s * y;
                                        V[k * 3 + q] = s * x + c * y;
                                }
                        }
        }
        for (int i = 0; i < 3; i++)
                w[i] = a[i * 4];
}

int cal_plane_fit(const double *p, size_t n, struct cal_plane *pl, double *rms, double *spread)
{
        double c[3] = {0}, C[9] = {0}, w[3], V[9];
        int lo = 0, mid;

        if (n < 3)
                return -EINVAL;
        for (size_t i = 0; i < n; i++)
                for (int k = 0; k < 3; k++)
                        c[k] += p[3 * i + k] / n;
        for (size_t i = 0; i < n; i++)
                for (int r = 0; r < 3; r++)
                        for (int k = 0; k < 3; k++)
                                C[r * 3 + k] += (p[3 * i + r] - c[r]) * (p[3 * i + k] - c[k]) / n;
        cal_eig3(C, w, V);
        for (int k = 1; k < 3; k++)
                lo = w[k] < w[lo] ? k : lo;
        mid = (lo + 1) % 3;
        mid = w[(lo + 2) % 3] < w[mid] ? (lo + 2) % 3 : mid;
        for (int k = 0; k < 3; k++)
                pl->n[k] = V[k * 3 + lo];
        pl->d = -cal_dot(pl->n, c);
        if (rms)
                *rms = sqrt(fmax(w[lo], 0));
        if (spread)
                *spread = sqrt(fmax(w[mid], 0));
        return 0;
}

void cal_rodrigues(const double r[3], double R[9])
{
        double th = sqrt(cal_dot(r, r)), k[3], c, s;

        if (th < 1e-15) {
                double I[9] = {1, -r[2], r[1], r[2], 1, -r[0], -r[1], r[0], 1};
                memcpy(R, I, sizeof(I));
                return;
        }
        for (int i = 0; i < 3; i++)
                k[i] = r[i] / th;
        c = cos(th);
        s = sin(th);
        for (int i = 0; i < 3; i++)
                for (int j = 0; j < 3; j++)
                        R[i * 3 + j] = (1 - c) * k[i] * k[j] + (i == j ? c : 0);
        R[1] -= s * k[2];
        R[2] += s * k[1];
        R[3] += s * k[2];
        R[5] -= s * k[0];
        R[6] -= s * k[1];
        R[7] += s * k[0];
}

double cal_dot(const double a[3], const double b[3])
{
        return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

void cal_cross(const double a[3], const double b[3], double c[3])
{
        c[0] = a[1] * b[2] - a[2] * b[1];
        c[1] = a[2] * b[0] - a[0] * b[2];
        c[2] = a[0] * b[1] - a[1] * b[0];
}

void cal_normalize(double a[3])
{
        double l = sqrt(cal_dot(a, a));

        for (int i = 0; i < 3; i++)
                a[i] /= l;
}

void cal_mat_vec(const double R[9], const double x[3], double y[3])
{
        for (int i = 0; i < 3; i++)
                y[i] = R[i * 3] * x[0] + R[i * 3 + 1] * x[1] + R[i * 3 + 2] * x[2];
}

void cal_mat_mul(const double A[9], const double B[9], double C[9])
{
        for (int i = 0; i < 3; i++)
                for (int j = 0; j < 3; j++)
                        C[i * 3 + j] =
                                A[i * 3] * B[j] + A[i * 3 + 1] * B[3 + j] + A[i * 3 + 2] * B[6 + j];
}

void cal_basis(const double n[3], double e1[3], double e2[3])
{
        double a[3] = {fabs(n[0]) < 0.9 ? 1 : 0, fabs(n[0]) < 0.9 ? 0 : 1, 0};

        cal_cross(n, a, e1);
        cal_normalize(e1);
        cal_cross(n, e1, e2);
}

int cal_solve(double *A, double *b, int n)
{
        for (int c = 0; c < n; c++) {
                int piv = c;
                for (int r = c + 1; r < n; r++)
                        piv = fabs(A[r * n + c]) > fabs(A[piv * n + c]) ? r : piv;
                if (fabs(A[piv * n + c]) < 1e-300)
                        return -EDOM;
                for (int k = 0; k < n; k++) {
                        double t = A[c * n + k];
                        A[c * n + k] = A[piv * n + k];
                        A[piv * n + k] = t;
                }
                double t = b[c];
                b[c] = b[piv];
                b[piv] = t;
                for (int r = c + 1; r < n; r++) {
                        double f = A[r * n + c] / A[c * n + c];
                        for (int k = c; k < n; k++)
                                A[r * n + k] -= f * A[c * n + k];
                        b[r] -= f * b[c];
                }
        }
        for (int c = n - 1; c >= 0; c--) {
                for (int k = c + 1; k < n; k++)
                        b[c] -= A[c * n + k] * b[k];
                b[c] /= A[c * n + c];
        }
        return 0;
}

int cal_circle_fit(const double *xy, size_t n, double c[2], double *r)
{
        double A[9] = {0}, b[3] = {0};

        if (n < 3)
                return -EINVAL;
        for (size_t i = 0; i < n; i++) { /* x^2 + y^2 + D x + E y + F = 0 */
                double row[3] = {xy[2 * i], xy[2 * i + 1], 1};
                double rhs = -(row[0] * row[0] + row[1] * row[1]);
                for (int j = 0; j < 3; j++) {
                        for (int k = 0; k < 3; k++)
                                A[j * 3 + k] += row[j] * row[k];
                        b[j] += row[j] * rhs;
                }
        }
        if (cal_solve(A, b, 3) < 0)
                return -EDOM;
        c[0] = -b[0] / 2;
        c[1] = -b[1] / 2;
        *r = sqrt(fmax(c[0] * c[0] + c[1] * c[1] - b[2], 0));
        return 0;
}
