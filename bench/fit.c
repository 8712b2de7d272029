/* bench/fit.c - the appearance fit (appearance/fit.h) of the seed-scale synthetic dataset
 * (bench/seedset.h: 76 views x 100 lights x 720x480 by default), fitted end to end (SH order 6 +
 * PCA K 12, written), against in the same run the time to merely decode its images (2 threads) and
 * the time of the fit's matrix products (36 x L by L x 3N per view, OpenBLAS on 2 threads).
 * Targets: fit at most 60 s on 2 cores and at most 2 x (decode + product). Options: --turntable N
 * (views per camera: fewer for a smaller run), --arm N, --cameras N, --dir DIR. The CPU seconds of
 * each part go to stderr (the machine is shared: wall times move with its load). Last line: one
 * JSON object. */
#include <cblas.h>
#include <errno.h>
#include <fcntl.h>
#include <getopt.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "bench/clock.h"
#include "bench/seedset.h"
#include "appearance/fit.h"
#include "common/cleanup.h"
#include "common/fileio.h"
#include "dataset/ds.h"
#include "dataset/ds_png.h"
#include "drivers/registry.h"
#include "sim/render/render.h"

/* Seconds of the fit's products: per view 36 x L by L x 3N, OpenBLAS on 2 threads. */
static double gemm_all(int views, int lights)
{
        size_t N = 3 * 720 * 480;
        float *P = calloc((size_t)36 * lights, sizeof(float)),
              *D = malloc(N * lights * sizeof(float));
        float *C = malloc(N * 36 * sizeof(float));
        double t0;

        if (!P || !D || !C)
                seedset_die("gemm", -ENOMEM);
        for (size_t i = 0; i < N * lights; i++)
                D[i] = (float)(i % 251) / 251;
        openblas_set_num_threads(2);
        t0 = bench_wall_s();
        for (int v = 0; v < views; v++)
                cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, 36, (int)N, lights, 1, P,
                            lights, D, (int)N, 0, C, (int)N);
        t0 = bench_wall_s() - t0;
        free(P), free(D), free(C);
        return t0;
}

int main(int argc, char **argv)
{
        struct ap_fit_opts fo;
        struct ap_model *m = NULL;
        struct seedset_opts o;
        struct ds *d;
        char err[1024];
        double fit_s, decode_s, gemm_s, cpu[4];
        int r;

        seedset_parse(argc, argv, &o);
        seedset_open(&o, &d);
        cpu[0] = bench_cpu_self_s();
        decode_s = seedset_decode_all(d);
        cpu[1] = bench_cpu_self_s();
        gemm_s = gemm_all(o.cameras * o.turntable, o.arm * SEEDSET_LAMPS);
        cpu[2] = bench_cpu_self_s();
        ap_fit_opts_default(&fo);
        fo.backends = registry_backends;
        fit_s = bench_wall_s();
        r = ap_fit(d, &fo, &m, err, sizeof(err));
        if (r == 0)
                r = ap_model_write(m, ds_path(d));
        fit_s = bench_wall_s() - fit_s;
        cpu[3] = bench_cpu_self_s();
        if (r < 0)
                seedset_die(err, r);
        fprintf(stderr,
                "bench/fit: %zu views: fit %.1f s (rms sh %.4f, pca %.4f; %s), decode %.1f "
                "s, products %.1f s: %.2f x (decode + products); CPU seconds: fit %.1f, decode "
                "%.1f, products %.1f\n",
                m->n_views, fit_s, m->rms_sh, m->rms_pca, m->notes, decode_s, gemm_s,
                fit_s / (decode_s + gemm_s), cpu[3] - cpu[2], cpu[1] - cpu[0], cpu[2] - cpu[1]);
        printf("{\"bench\":\"fit\",\"fit_s\":%.2f,\"decode_s\":%.2f,\"gemm_s\":%.2f,\"views\":%d,"
               "\"lights\":%d}\n",
               fit_s, decode_s, gemm_s, o.cameras * o.turntable, o.arm * SEEDSET_LAMPS);
        ap_model_free(m);
        ds_close(d);
        return 0;
}
