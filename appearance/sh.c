/* sh.c - real spherical harmonics of any order up to AP_ORDER_MAX (sh.h), by the standard
 * recurrences: for each m the azimuthal part Re/Im (x + iy)^m, the polar part
 * P_l^m(z) / sin^m(theta) by
 *     Q_m^m = (2m - 1)!!,  Q_{m+1}^m = (2m + 1) z Q_m^m,
 *     Q_l^m = ((2l - 1) z Q_{l-1}^m - (l + m - 1) Q_{l-2}^m) / (l - m),
 * times the normalisation sqrt((2l + 1) / 4pi (l - m)! / (l + m)!) (and sqrt 2 for m != 0).
 * No Condon-Shortley phase: Y_{1,-1}, Y_{1,0}, Y_{1,1} are sqrt(3 / 4pi) (y, z, x). */
#include <math.h>
#include <pthread.h>

#include "appearance/model.h"
#include "appearance/sh.h"

#define N_MAX (AP_ORDER_MAX * AP_ORDER_MAX)

/* norm[l * l + l + m] for m >= 0: the normalisation times (2m - 1)!!. */
static double norm_d[N_MAX];
static float norm_f[N_MAX];
static pthread_once_t norm_once = PTHREAD_ONCE_INIT;

static void norm_init(void)
{
        for (int l = 0; l < AP_ORDER_MAX; l++) {
                double dfact = 1; /* (2m - 1)!! */
                for (int m = 0; m <= l; m++) {
                        double ratio = 1; /* (l + m)! / (l - m)! */
                        if (m > 0)
                                dfact *= 2 * m - 1;
                        for (int k = l - m + 1; k <= l + m; k++)
                                ratio *= k;
                        norm_d[l * l + l + m] =
                                sqrt((2 * l + 1) / (4 * M_PI) / ratio) * dfact * (m ? M_SQRT2 : 1);
                        norm_f[l * l + l + m] = (float)norm_d[l * l + l + m];
                }
        }
}

/* One body for double and float: y[0 .. order^2) at direction d, with the table nrm. */
#define SH_EVAL_BODY(T, order, d, y, nrm)                                                          \
        do {                                                                                       \
                T x = d[0], yy = d[1], z = d[2], c = 1, s = 0;                                     \
                for (int m = 0; m < (order); m++) {                                                \
                        T q0 = 1, q1 = 0; /* Q_{l-1}, Q_{l-2} without (2m-1)!! */                  \
                        if (m > 0) {                                                               \
                                T cn = c * x - s * yy;                                             \
                                s = c * yy + s * x;                                                \
                                c = cn;                                                            \
                        }                                                                          \
                        for (int l = m; l < (order); l++) {                                        \
                                T q = l == m ? 1 : l == m + 1 ? (2 * m + 1) * z : 0;               \
                                if (l > m + 1)                                                     \
                                        q = ((2 * l - 1) * z * q0 - (l + m - 1) * q1) / (l - m);   \
                                q1 = q0;                                                           \
                                q0 = q;                                                            \
                                y[l * l + l + m] = nrm[l * l + l + m] * q * c;                     \
                                if (m > 0)                                                         \
                                        y[l * l + l - m] = nrm[l * l + l + m] * q * s;             \
                        }                                                                          \
                }                                                                                  \
        } while (0)

void ap_sh_eval(int order, const double d[3], double *y)
{
        pthread_once(&norm_once, norm_init);
        SH_EVAL_BODY(double, order, d, y, norm_d);
}

void ap_sh_evalf(int order, const float d[3], float *y)
{
        pthread_once(&norm_once, norm_init);
        SH_EVAL_BODY(float, order, d, y, norm_f);
}
