/* rtest.c - helpers for the renderer's tests (see rtest.h). */
#include <spng.h>
#include <stdio.h>
#include <unistd.h>

#include "drivers/registry.h"
#include "rtest.h"

static const char header[] = "rig: render-test\n"
                             "buses:\n"
                             "  - { name: relays, type: modbus-rtu, port: /nonexistent/relays }\n"
                             "  - { name: frames, type: sim, port: /nonexistent/frames.sock }\n";

int rt_try_open(struct rtest *t, const char *lamps, const char *laser, const char *cameras,
                const char *scene, char *err, size_t errlen)
{
        FILE *f;
        int fd, r;

        memset(t, 0, sizeof(*t));
        snprintf(t->path, sizeof(t->path), "/tmp/gonio-rtest-XXXXXX.yaml");
        fd = mkstemps(t->path, 5);
        CHECK(fd >= 0);
        f = fdopen(fd, "w");
        CHECK(f);
        fprintf(f, "%s%s\n%s\n%s\n%s\n", header, lamps, laser, cameras, scene);
        fclose(f);
        r = rigconf_load(t->path, registry_backends, &t->rc, err, errlen);
        if (r >= 0)
                r = sim_scene_new(t->rc, &t->s, err, errlen);
        return r;
}

void rt_open(struct rtest *t, const char *lamps, const char *laser, const char *cameras,
             const char *scene)
{
        char err[512];
        int r = rt_try_open(t, lamps, laser, cameras, scene, err, sizeof(err));

        if (r < 0)
                fprintf(stderr, "rt_open: %s\n", err);
        CHECK_INT(r, 0);
}

void rt_close(struct rtest *t)
{
        sim_scene_free(t->s);
        rigconf_free(t->rc);
        unlink(t->path);
        memset(t, 0, sizeof(*t));
}

void rt_render(struct rtest *t, const struct gn_pose *st, const struct sim_expose *ex, uint64_t seq,
               struct gn_frame *f, unsigned flags, struct sim_truth *truth)
{
        CHECK_INT(sim_render(t->s, st, 0, ex, seq, f, flags, truth), 0);
}

double rt_px(const struct gn_frame *f, int x, int y, int ch)
{
        const uint8_t *row = f->data + (size_t)y * f->stride;

        if (f->bits == 8)
                return row[(size_t)x * f->channels + ch];
        return ((const uint16_t *)row)[(size_t)x * f->channels + ch];
}

void rt_dump(const struct gn_frame *f, const char *name)
{
        const char *dir = getenv("RTEST_DUMP");
        struct spng_ihdr ih = {0};
        char path[512];
        spng_ctx *c;
        FILE *o;

        if (!dir || f->bits != 8)
                return;
        snprintf(path, sizeof(path), "%s/%s.png", dir, name);
        o = fopen(path, "wb");
        c = spng_ctx_new(SPNG_CTX_ENCODER);
        if (o && c) {
                ih.width = f->width;
                ih.height = f->height;
                ih.bit_depth = 8;
                ih.color_type =
                        f->channels == 3 ? SPNG_COLOR_TYPE_TRUECOLOR : SPNG_COLOR_TYPE_GRAYSCALE;
                spng_set_png_file(c, o);
                spng_set_ihdr(c, &ih);
                spng_encode_image(c, f->data, gn_frame_bytes(f), SPNG_FMT_PNG,
                                  SPNG_ENCODE_FINALIZE);
        }
        spng_ctx_free(c);
        if (o)
                fclose(o);
}
