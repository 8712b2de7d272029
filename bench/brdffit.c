/* bench/brdffit.c - the BRDF fit (appearance/brdf_fit.h) of the seed-scale synthetic dataset
 * (bench/seedset.h: 76 views x 100 lights x 720x480 by default, a 250 mm sphere of a Beckmann
 * lobe), end to end with the default 20000 texels on 2 threads, against in the same run the
 * time to merely read and decode its images. Options as bench/fit (--turntable N ...) and
 * --texels N. The CPU seconds go to stderr (the machine is shared). Last line: one JSON
 * object {"bench":"brdffit","texels_per_s":..,"read_s":..,"fit_s":..}. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "appearance/brdf_fit.h"
#include "bench/clock.h"
#include "bench/seedset.h"
#include "drivers/registry.h"

/* --texels N out of argv (the rest is seedset_parse's). */
static size_t take_texels(int *argc, char **argv)
{
        size_t texels = AP_BRDF_TEXELS_DEFAULT;

        for (int i = 1; i + 1 < *argc; i++)
                if (!strcmp(argv[i], "--texels")) {
                        texels = strtoul(argv[i + 1], NULL, 10);
                        memmove(&argv[i], &argv[i + 2], (*argc - i - 1) * sizeof(char *));
                        *argc -= 2;
                        break;
                }
        return texels;
}

int main(int argc, char **argv)
{
        struct ap_brdf_fit_opts fo;
        struct ap_brdf_model *m = NULL;
        struct seedset_opts o;
        struct ds *d;
        char err[1024] = "";
        double read_s, fit_s, cpu[3];
        size_t n, fitted = 0, texels = take_texels(&argc, argv);
        int r;

        seedset_parse(argc, argv, &o);
        seedset_open(&o, &d);
        cpu[0] = bench_cpu_self_s();
        read_s = seedset_decode_all(d);
        cpu[1] = bench_cpu_self_s();
        ap_brdf_fit_opts_default(&fo);
        fo.backends = registry_backends;
        fo.texels = texels;
        fit_s = bench_wall_s();
        r = ap_brdf_fit(d, &fo, &m, err, sizeof(err));
        fit_s = bench_wall_s() - fit_s;
        cpu[2] = bench_cpu_self_s();
        if (r < 0)
                seedset_die(err, r);
        n = (size_t)m->atlas.width * m->atlas.height;
        for (size_t i = 0; i < n; i++)
                fitted += !(m->texels[i].flags & AP_BRDF_MASKED);
        fprintf(stderr,
                "bench/brdffit: %zu texels fitted (%zu in the atlas) in %.1f s, of which %.1f s "
                "gathering the samples; decoding the images alone %.1f s: the fit %.2f x the read; "
                "CPU seconds: fit %.1f, decode %.1f (%s)\n",
                fitted, n, fit_s, m->read_seconds, read_s, fit_s / read_s, cpu[2] - cpu[1],
                cpu[1] - cpu[0], m->notes);
        printf("{\"bench\":\"brdffit\",\"texels_per_s\":%.1f,\"read_s\":%.2f,\"fit_s\":%.2f}\n",
               fitted / fit_s, read_s, fit_s);
        ap_brdf_model_free(m);
        ds_close(d);
        return 0;
}
