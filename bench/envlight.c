/* envlight.c - issue 12's environment relighting benchmark: a glossy anisotropic sphere on
 * the turntable disc under a sky with a sun (tests/appearance/envscene.h), 640x480: gonio-sim's
 * converged dome reference (the map split into up to 4096 lights with shadow rays) against the
 * BRDF model relit by render_env.h (prefiltered maps, 32 spheres) on 2 threads; the set-up
 * (prefiltering, sphere fit, per-vertex visibility) timed apart; the frames' CPU time too
 * (wall-clock fps depends on what else runs on the machine). Targets: at least 30 frames/s,
 * 100x the reference, PSNR >= 33 dB. Last line:
 * {"bench":"envlight","fps":...,"reference_s_per_frame":...,"psnr_db":...,"spheres":...}. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "bench/clock.h"
#include "appearance/render_env.h"
#include "common/clock.h"
#include "tests/appearance/envscene.h"

#define FRAMES  120
#define SPHERES 32
#define THREADS 2

int main(void)
{
        static const struct envscene_opts o = {
                .width = 640,
                .height = 480,
                .elevation = 30,
                .env_width = 512,
                .dome_elements = 4096,
                .ks = 0.3,
                .ax = 0.15,
                .ay = 0.08,
                .ground_radius = 150,
        };
        struct ap_prefilter_params pp = {16,          96,        (float)o.ax, (float)o.ay,
                                         ENVSCENE_F0, {0, 0, 1}, THREADS};
        size_t n = (size_t)o.width * o.height;
        float *ref = malloc(3 * n * sizeof(float)), *img = malloc(3 * n * sizeof(float));
        uint8_t *mask = malloc(n);
        struct envscene es;
        struct ap_prefilter pf;
        struct ap_spheres sp;
        struct ap_env_renderer *r = NULL;
        double ref_s, t0, t_pf, t_sp, t_new, t_frames, cpu0, cpu_frames, psnr;

        if (!ref || !img || !mask)
                return 1;
        envscene_open(&es, &o);
        envscene_reference(&es, ref, &ref_s);
        printf("reference: gonio-sim, %d dome elements, %.2f s a frame\n", o.dome_elements, ref_s);
        t0 = bench_wall_s();
        if (ap_prefilter_build(&es.env, &pp, &pf) < 0)
                return 1;
        t_pf = bench_wall_s();
        if (ap_spheres_fit(&es.model->atlas.mesh, SPHERES, 32, &sp) < 0)
                return 1;
        t_sp = bench_wall_s();
        struct ap_env_scene sc = {
                es.model, &es.env, &pf, &sp, ENVSCENE_GROUND, (float)o.ground_radius, 1};
        if (ap_env_renderer_new(&sc, &r) < 0)
                return 1;
        t_new = bench_wall_s();
        printf("set-up: prefiltering %.2f s (%d normal pairs, %dx%d maps), %d spheres %.2f s, "
               "visibility %.2f s\n",
               t_pf - t0, pp.pairs, pf.width, pf.height, sp.n, t_sp - t_pf, t_new - t_sp);
        t0 = bench_wall_s();
        cpu0 = bench_cpu_self_s();
        for (int i = 0; i < FRAMES; i++)
                if (ap_env_render(r, &es.cam, THREADS, img, mask) < 0)
                        return 1;
        t_frames = (bench_wall_s() - t0) / FRAMES;
        cpu_frames = (bench_cpu_self_s() - cpu0) / FRAMES;
        for (size_t i = 0; i < n; i++)
                mask[i] = 1;
        psnr = envscene_psnr(img, ref, mask, n);
        printf("render_env: %.2f ms a frame (%.1f fps), %.0fx the reference, PSNR %.2f dB\n",
               1e3 * t_frames, 1 / t_frames, ref_s / t_frames, psnr);
        printf("cpu: %.2f ms a frame over the threads: %.1f fps on %d cores of its own\n",
               1e3 * cpu_frames, THREADS / cpu_frames, THREADS);
        envscene_dump(img, ref, o.width, o.height, "envlight");
        printf("{\"bench\":\"envlight\",\"fps\":%.1f,\"reference_s_per_frame\":%.3f,"
               "\"psnr_db\":%.2f,\"spheres\":%d}\n",
               1 / t_frames, ref_s, psnr, sp.n);
        ap_env_renderer_free(r);
        ap_spheres_free(&sp);
        ap_prefilter_free(&pf);
        envscene_close(&es);
        free(ref);
        free(img);
        free(mask);
        return 0;
}
