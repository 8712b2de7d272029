/* test-laserline.c - calib/laserline.c against the renderer's analytic laser line (noise on):
 * RMS <= 0.03 px (the default estimator; the lamp's shot noise included) over the rows where
 * the line is seen,
 * every such row found, and no point at all on rows without laser light (the ball hides the
 * line, or the plate ends), with speckle, an ambient lamp lit in the on frame only, a lamp in
 * both frames, one frame in a dark room and with a lamp, clipped peaks, two lines in a row,
 * 8 and 16 bits, columns, and the laser's channel only. */
#include <math.h>

#include "common/cleanup.h"
#include "lltest.h"

#define W       640
#define H       480
#define RMS_MAX 0.03 /* px */
#define POWER   1.2e3
#define LAMP    2.2e5

struct run {
        float centre[W], strength[W], width[W];
        struct laserline_result r;
};

static struct laserline_result *run_init(struct run *x)
{
        x->r = (struct laserline_result){
                .centre = x->centre, .strength = x->strength, .width = x->width, .n = W};
        return &x->r;
}

/* Extracts with o and checks the score: no spurious point, no visible row missed, RMS. */
static double expect(const struct llscene *s, const struct gn_frame *on, const struct gn_frame *off,
                     const struct laserline_opts *o, double rms_max, const char *what)
{
        struct run x;
        int visible, missed, spurious, hidden = 0;
        double rms, strength = 0, width = 0;

        CHECK(laserline_extract(on, off, o, run_init(&x)) >= 0);
        rms = ll_score(s, &x.r, &visible, &missed, &spurious);
        for (int v = 0; v < s->h; v++)
                if (s->row[v] == LL_VISIBLE && !isnan(x.centre[v])) {
                        strength = fmax(strength, x.strength[v]);
                        width = fmax(width, x.width[v]);
                }
        for (int v = 0; v < s->h; v++)
                hidden += s->row[v] == LL_GAP && !isnan(s->u[v]);
        fprintf(stderr,
                "%s: %d visible rows, %d missed, %d spurious, %d hidden by the ball, "
                "RMS %.4f px, strength <= %.0f DN, width <= %.2f px, %d ambiguous\n",
                what, visible, missed, spurious, hidden, rms, strength, width, x.r.ambiguous);
        CHECK(visible > 100 && hidden > 10);
        CHECK_INT(spurious, 0);
        CHECK_INT(missed, 0);
        CHECK(rms <= rms_max);
        return rms;
}

static void test_accuracy(void)
{
        static const char *names[] = {"gauss3", "com", "parabola", "weighted"};
        struct run x;
        struct llscene s;
        struct gn_frame on, off;
        struct laserline_opts o;

        ll_open(&s, W, H, POWER, 0);
        for (int bits = 8; bits <= 16; bits += 8) {
                ll_render(&s, true, false, bits, 1, &on);
                ll_render(&s, false, false, bits, 2, &off);
                for (int e = LASERLINE_GAUSS3; e <= LASERLINE_WEIGHTED; e++) {
                        char what[64];
                        laserline_opts_default(&o, 0);
                        o.estimator = e;
                        snprintf(what, sizeof(what), "%d bits, %s", bits, names[e]);
                        expect(&s, &on, &off, &o,
                               e == LASERLINE_COM || e == LASERLINE_WEIGHTED ? RMS_MAX : 1, what);
                }
                /* the laser is red: the green channel has no line */
                laserline_opts_default(&o, 1);
                CHECK_INT(laserline_extract(&on, &off, &o, run_init(&x)), 0);
                CHECK_INT(laserline_extract(&on, NULL, &o, run_init(&x)), 0);
                gn_frame_free_data(&on);
                gn_frame_free_data(&off);
        }
        ll_close(&s);
}

/* Sets n isolated pixels of f (every channel) to full scale, none within 8 px of the line. */
static void speckle(const struct llscene *s, struct gn_frame *f, int n)
{
        uint32_t seed = 12345;

        for (int i = 0; i < n;) {
                int u, v;
                seed = seed * 1664525u + 1013904223u;
                u = (int)(seed >> 8) % f->width;
                v = (int)((seed >> 4) % (uint32_t)f->height);
                if (!isnan(s->u[v]) && fabs(u - s->u[v]) < 8)
                        continue;
                for (int c = 0; c < f->channels; c++)
                        if (f->bits == 8)
                                f->data[v * f->stride + (size_t)u * f->channels + c] = 255;
                        else
                                ((uint16_t *)(f->data + v * f->stride))[u * f->channels + c] =
                                        65535;
                i++;
        }
}

static void test_speckle(void)
{
        struct llscene s;
        struct gn_frame on, off;
        struct laserline_opts o;

        laserline_opts_default(&o, 0);
        ll_open(&s, W, H, POWER, 0);
        for (int bits = 8; bits <= 16; bits += 8) {
                ll_render(&s, true, false, bits, 1, &on);
                ll_render(&s, false, false, bits, 2, &off);
                speckle(&s, &on, 2000);
                expect(&s, &on, &off, &o, RMS_MAX,
                       bits == 8 ? "speckle, 8 bits" : "speckle, 16 bits");
                expect(&s, &on, NULL, &o, RMS_MAX, "speckle, one frame");
                gn_frame_free_data(&on);
                gn_frame_free_data(&off);
        }
        ll_close(&s);
}

/* A lamp lit in the on frame only, in both, and one frame with the lamp. */
static void test_ambient(void)
{
        struct llscene s;
        struct gn_frame on, off, lamp;
        struct laserline_opts o;

        laserline_opts_default(&o, 0);
        ll_open(&s, W, H, POWER, LAMP);
        ll_render(&s, true, true, 8, 1, &on);
        ll_render(&s, false, false, 8, 2, &off);
        ll_render(&s, false, true, 8, 3, &lamp);
        expect(&s, &on, &off, &o, RMS_MAX, "lamp in the on frame only");
        expect(&s, &on, &lamp, &o, RMS_MAX, "lamp in both frames");
        expect(&s, &on, NULL, &o, RMS_MAX, "one frame with the lamp");
        gn_frame_free_data(&on);
        gn_frame_free_data(&off);
        gn_frame_free_data(&lamp);
        ll_close(&s);
}

/* One frame in a dark room (black level on): the baseline comes from the row. */
static void test_one_frame(void)
{
        struct llscene s;
        struct gn_frame on;
        struct laserline_opts o;

        laserline_opts_default(&o, 0);
        ll_open(&s, W, H, POWER, 0);
        for (int bits = 8; bits <= 16; bits += 8) {
                ll_render(&s, true, false, bits, 1, &on);
                expect(&s, &on, NULL, &o, RMS_MAX,
                       bits == 8 ? "one frame, 8 bits" : "one frame, 16 bits");
                gn_frame_free_data(&on);
        }
        ll_close(&s);
}

/* A laser 8 times too strong: clipped flat tops, centred on their half-height crossings. */
static void test_saturation(void)
{
        struct llscene s;
        struct gn_frame on, off;
        struct laserline_opts o;

        ll_open(&s, W, H, 8 * POWER, 0);
        for (int bits = 8; bits <= 16; bits += 8) {
                ll_render(&s, true, false, bits, 1, &on);
                ll_render(&s, false, false, bits, 2, &off);
                /* every estimator: a 3-point fit on a flat top would say nothing */
                for (int e = LASERLINE_GAUSS3; e <= LASERLINE_WEIGHTED; e++) {
                        laserline_opts_default(&o, 0);
                        o.estimator = e;
                        expect(&s, &on, &off, &o, RMS_MAX,
                               bits == 8 ? "clipped, 8 bits" : "clipped, 16 bits");
                }
                gn_frame_free_data(&on);
                gn_frame_free_data(&off);
        }
        ll_close(&s);
}

/* Adds k times the laser's light (on - off, red, 8 bits) shifted by dx px: a second line. */
static void second_line(struct gn_frame *on, const struct gn_frame *off, int dx, double k)
{
        for (int v = 0; v < on->height; v++)
                for (int u = on->width - 1 - dx; u >= 0; u--) {
                        uint8_t *a = on->data + v * on->stride, *b = off->data + v * off->stride;
                        double add = k * (a[3 * u] > b[3 * u] ? a[3 * u] - b[3 * u] : 0);
                        a[3 * (u + dx)] = (uint8_t)fmin(255, a[3 * (u + dx)] + lround(add));
                }
}

/* Two lines in a row: the row gets no point when the second is at least `ambiguity` as
 * high as the first; a weaker second line (a faint reflection) is ignored. */
static void test_ambiguous(void)
{
        struct llscene s;
        struct gn_frame on, off;
        struct laserline_opts o;
        struct run x;
        int visible, missed, spurious;

        laserline_opts_default(&o, 0);
        ll_open(&s, W, H, POWER, 0);
        ll_render(&s, true, false, 8, 1, &on);
        ll_render(&s, false, false, 8, 2, &off);
        second_line(&on, &off, 40, 0.3);
        expect(&s, &on, &off, &o, RMS_MAX, "a reflection 0.3 as bright, 40 px away");
        second_line(&on, &off, 40, 0.5); /* now 0.8 as bright */
        CHECK(laserline_extract(&on, &off, &o, run_init(&x)) >= 0);
        ll_score(&s, &x.r, &visible, &missed, &spurious);
        fprintf(stderr,
                "a second line 0.8 as bright: %d of %d rows rejected as ambiguous, %d "
                "points\n",
                x.r.ambiguous, visible, x.r.points);
        CHECK_INT(missed, visible);
        CHECK_INT(spurious, 0);
        CHECK(x.r.ambiguous >= visible);
        gn_frame_free_data(&on);
        gn_frame_free_data(&off);
        ll_close(&s);
}

static void transpose(const struct gn_frame *f, struct gn_frame *t)
{
        CHECK_INT(gn_frame_alloc(t, f->height, f->width, f->channels, f->bits), 0);
        for (int v = 0; v < f->height; v++)
                for (int u = 0; u < f->width; u++)
                        memcpy(t->data + u * t->stride + (size_t)v * f->channels,
                               f->data + v * f->stride + (size_t)u * f->channels,
                               (size_t)f->channels);
}

/* A centre per column of the transposed frames equals the centre per row of the frames. */
static void test_columns(void)
{
        struct llscene s;
        struct gn_frame on, off, ton, toff;
        struct laserline_opts o;
        struct run rows, cols;

        laserline_opts_default(&o, 0);
        ll_open(&s, W, H, POWER, 0);
        ll_render(&s, true, false, 8, 1, &on);
        ll_render(&s, false, false, 8, 2, &off);
        transpose(&on, &ton);
        transpose(&off, &toff);
        CHECK(laserline_extract(&on, &off, &o, run_init(&rows)) > 100);
        o.columns = true;
        CHECK_INT(laserline_extract(&ton, &toff, &o, run_init(&cols)), rows.r.points);
        CHECK_INT(cols.r.n, H);
        for (int v = 0; v < H; v++)
                CHECK(memcmp(&rows.centre[v], &cols.centre[v], sizeof(float)) == 0);
        gn_frame_free_data(&on);
        gn_frame_free_data(&off);
        gn_frame_free_data(&ton);
        gn_frame_free_data(&toff);
        ll_close(&s);
}

static void test_args(void)
{
        _cleanup_(gn_frame_free_data) struct gn_frame a = {0}, b = {0}, wide = {0};
        struct laserline_opts o;
        struct run x;

        laserline_opts_default(&o, 0);
        CHECK_INT(gn_frame_alloc(&a, 64, 32, 3, 8), 0);
        CHECK_INT(gn_frame_alloc(&b, 64, 32, 3, 16), 0);
        CHECK_INT(gn_frame_alloc(&wide, LASERLINE_MAX_LEN + 1, 2, 1, 8), 0);
        CHECK_INT(laserline_extract(&a, NULL, &o, run_init(&x)), 0);
        CHECK_INT(x.r.n, 32);
        CHECK(isnan(x.centre[0]) && isnan(x.centre[31]));
        CHECK_INT(laserline_extract(&a, &b, &o, run_init(&x)), -EINVAL);
        o.channel = 3;
        CHECK_INT(laserline_extract(&a, NULL, &o, run_init(&x)), -EINVAL);
        o.channel = 0;
        x.r.n = 31;
        CHECK_INT(laserline_extract(&a, NULL, &o, &x.r), -EINVAL);
        CHECK_INT(laserline_extract(&wide, NULL, &o, run_init(&x)), -E2BIG);
}

static const struct test_case cases[] = {
        {"accuracy", test_accuracy},     {"speckle", test_speckle},
        {"ambient", test_ambient},       {"one-frame", test_one_frame},
        {"saturation", test_saturation}, {"columns", test_columns},
        {"ambiguous", test_ambiguous},   {"args", test_args},
};

int main(int argc, char **argv)
{
        return test_run_cases(cases, sizeof(cases) / sizeof(cases[0]), argc, argv);
}
