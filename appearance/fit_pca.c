/* fit_pca.c - the PCA of the fit (fit_internal.h): the mean and the K leading eigenvectors
 * of the covariance of the sampled coefficient vectors (LAPACKE), and the projection of a
 * view's vectors on them by one matrix product (OpenBLAS). */
#include <cblas.h>
#include <errno.h>
#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "appearance/fit_internal.h"
#include "common/cleanup.h"

/* The sample's vectors (dimension D): every stride-th vector kept by each pilot view, in
 * view order, into X; their number. X NULL: only counted. */
static size_t gather(const struct fit_ctx *c, int D, double *X)
{
        size_t n = 0;

        for (size_t v = 0; v < c->n_views; v++)
                for (size_t i = 0; c->views[v].pilot && i < c->views[v].n_kept; i += c->stride, n++)
                        for (int j = 0; X && j < D; j++)
                                X[n * D + j] = c->views[v].kept[i * D + j];
        return n;
}

/* The mean of the n sample vectors X (dimension D) into mean; X centred. */
static void centre(double *X, size_t n, int D, double *mean)
{
        memset(mean, 0, D * sizeof(double));
        for (size_t i = 0; i < n; i++)
                for (int j = 0; j < D; j++)
                        mean[j] += X[i * D + j];
        for (int j = 0; j < D; j++)
                mean[j] /= (double)n;
        for (size_t i = 0; i < n; i++)
                for (int j = 0; j < D; j++)
                        X[i * D + j] -= mean[j];
}

/* The RMS of the sample's residual after projection on the model's basis. */
static double residual_rms(const struct ap_model *m, const double *X, size_t n)
{
        int D = 3 * m->n_coef;
        double sse = 0;

        for (size_t i = 0; i < n; i++) {
                double w[AP_K_MAX] = {0};
                for (int k = 0; k < m->k; k++)
                        for (int j = 0; j < D; j++)
                                w[k] += m->basis[k * D + j] * X[i * D + j];
                for (int j = 0; j < D; j++) {
                        double e = X[i * D + j];
                        for (int k = 0; k < m->k; k++)
                                e -= w[k] * m->basis[k * D + j];
                        sse += e * e;
                }
        }
        return sqrt(sse / ((double)n * D));
}

int fit_pca(struct fit_ctx *c)
{
        struct ap_model *m = c->model;
        int D = 3 * c->M;
        size_t n = c->n_sample = gather(c, D, NULL);
        _cleanup_free_ double *X = calloc(n * D, sizeof(double));
        _cleanup_free_ double *cov = calloc((size_t)D * D, sizeof(double));
        _cleanup_free_ double *mean = malloc(D * sizeof(double));
        _cleanup_free_ double *ev = malloc(D * sizeof(double));

        if (n < 2)
                return -ENODATA;
        if (!X || !cov || !mean || !ev)
                return -ENOMEM;
        gather(c, D, X);
        centre(X, n, D, mean);
        cblas_dsyrk(CblasRowMajor, CblasUpper, CblasTrans, D, (int)n, 1.0 / (n - 1), X, D, 0, cov,
                    D);
        if (LAPACKE_dsyevd(LAPACK_ROW_MAJOR, 'V', 'U', D, cov, D, ev) != 0)
                return -EDOM;
        for (int j = 0; j < D; j++)
                m->mean[j] = (float)mean[j];
        for (int k = 0; k < m->k; k++) { /* ascending: the last columns lead */
                int col = D - 1 - k, big = 0;
                for (int j = 0; j < D; j++)
                        big = fabs(cov[j * D + col]) > fabs(cov[big * D + col]) ? j : big;
                for (int j = 0; j < D; j++) /* sign: the largest entry positive */
                        m->basis[k * D + j] = (float)(cov[big * D + col] < 0 ? -cov[j * D + col]
                                                                             : cov[j * D + col]);
        }
        m->rms_pca = residual_rms(m, X, n);
        return 0;
}

void fit_pca_project(const struct ap_model *m, const float *coef, size_t n, float *w)
{
        int D = 3 * m->n_coef;
        float mb[AP_K_MAX] = {0};

        if (n == 0)
                return;
        for (int k = 0; k < m->k; k++)
                for (int j = 0; j < D; j++)
                        mb[k] += m->basis[k * D + j] * m->mean[j];
        cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasTrans, (int)n, m->k, D, 1, coef, D, m->basis,
                    D, 0, w, m->k);
        for (size_t i = 0; i < n; i++)
                for (int k = 0; k < m->k; k++)
                        w[i * m->k + k] -= mb[k];
}
