/* turntable_geom.h - small 3D geometry for turntable.c and laserplane.c (row-major 3x3). */
#pragma once

#include <stddef.h>

/* a . b */
double cal_dot(const double a[3], const double b[3]);
/* c = a x b (c distinct from a and b). */
void cal_cross(const double a[3], const double b[3], double c[3]);
/* Scales a to unit length (a must not be 0). */
void cal_normalize(double a[3]);
/* y = R x. */
void cal_mat_vec(const double R[9], const double x[3], double y[3]);
/* C = A B. */
void cal_mat_mul(const double A[9], const double B[9], double C[9]);
/* Two unit vectors e1, e2 completing the unit n to a right-handed basis. */
void cal_basis(const double n[3], double e1[3], double e2[3]);
/* Eigenvalues w and eigenvectors (columns of V) of the symmetric A (Jacobi). */
void cal_eig3(const double A[9], double w[3], double V[9]);
/* Solves A x = b (n x n, destroyed) in place into b. Returns 0 or -EDOM (singular). */
int cal_solve(double *A, double *b, int n);
/* Algebraic (Kasa) circle through n >= 3 points xy (2n): centre c, radius *r. Returns 0,
 * -EINVAL or -EDOM (collinear points). */
int cal_circle_fit(const double *xy, size_t n, double c[2], double *r);
