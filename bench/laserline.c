/* bench/laserline.c - the laser line's extraction (calib/laserline, on minus off) on 1280x960
 * RGB8 frames rendered once (tests/calib/lltest: the laser on a plate, noise on), against two
 * OpenCV references (laserline-ref.cpp: the Horus scanner's segmentation ported, in the JSON
 * line, and a tuned version of the same steps, printed) and against merely reading both frames
 * from memory (one thread summing them as 64-bit words). Ours on one thread and on two (a half
 * of the rows each; the faster of the two in the JSON line, as a caller would choose); the
 * references with OpenCV's threads (in the JSON line) and on one. Every kind is timed in turn
 * within each round, the best round kept. Also the RMS of each one's centres against the renderer's
 * analytic line. Last line: one JSON object. */
#include <math.h>
#include <pthread.h>
#include <semaphore.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/clock.h"
#include "laserline-ref.h"
#include "tests/calib/lltest.h"

#define W      1280
#define H      960
#define ROUNDS 15 /* the best round of each is kept: the machine is shared */

static double now_ms(void)
{
        return (double)gn_monotonic_ns() * 1e-6;
}

static volatile uint64_t sink;

/* Sums both frames as 64-bit words (every byte read once, as fast as the loop goes). */
static void memread(const struct gn_frame *on, const struct gn_frame *off)
{
        const uint64_t *a = (const uint64_t *)on->data, *b = (const uint64_t *)off->data;
        uint64_t s = 0;

        for (size_t i = 0; i < gn_frame_bytes(on) / 8; i++)
                s += a[i] + b[i];
        sink = s;
}

/* One half of the frames' rows (a view of them) and its results. */
struct half {
        struct gn_frame on, off;
        struct laserline_result r;
};

struct timed {
        const struct gn_frame *on, *off;
        struct laserline_opts o;
        struct laserline_result r;
        struct llref *ref;
        float ref_centre[H];
        struct half half[2]; /* OURS2: the main thread does half[0], the worker half[1] */
        pthread_t worker;
        sem_t go, done;
        bool quit;
};

enum { OURS2, OURS, HORUS, HORUS1, TUNED, TUNED1, MEMREAD, KINDS }; /* *1: one thread */

/* Splits the frames and t->r into two halves of rows, for two threads. */
static void halves(struct timed *t)
{
        for (int k = 0; k < 2; k++) {
                struct half *h = &t->half[k];
                int v0 = k * (H / 2);
                h->on = *t->on;
                h->off = *t->off;
                h->on.data += v0 * t->on->stride;
                h->off.data += v0 * t->off->stride;
                h->on.height = h->off.height = k ? H - H / 2 : H / 2;
                h->r = (struct laserline_result){.centre = t->r.centre + v0,
                                                 .strength = t->r.strength + v0,
                                                 .width = t->r.width + v0,
                                                 .n = h->on.height};
        }
}

static void *worker(void *arg)
{
        struct timed *t = arg;

        for (;;) {
                sem_wait(&t->go);
                if (t->quit)
                        return NULL;
                laserline_extract(&t->half[1].on, &t->half[1].off, &t->o, &t->half[1].r);
                sem_post(&t->done);
        }
}

/* Our extraction on two threads: each half of the rows on its own (laserline_extract is pure,
 * so a caller may split a frame so). */
static void ours2(struct timed *t)
{
        sem_post(&t->go);
        CHECK(laserline_extract(&t->half[0].on, &t->half[0].off, &t->o, &t->half[0].r) >= 0);
        sem_wait(&t->done);
}

static void run(struct timed *t, int what)
{
        if (what == OURS)
                CHECK(laserline_extract(t->on, t->off, &t->o, &t->r) > 0);
        else if (what == OURS2)
                ours2(t);
        else if (what == HORUS || what == HORUS1)
                CHECK_INT(llref_extract(t->ref, LLREF_HORUS, t->on, t->off, t->ref_centre), 0);
        else if (what == TUNED || what == TUNED1)
                CHECK_INT(llref_extract(t->ref, LLREF_TUNED, t->on, t->off, t->ref_centre), 0);
        else
                memread(t->on, t->off);
}

/* Milliseconds per frame of each kind: the best of ROUNDS rounds, each round timing every kind
 * in turn (n frames each), so that the ratios see the same load on a shared machine. */
static void time_all(struct timed *t, double best[KINDS])
{
        static const int frames[KINDS] = {50, 50, 10, 10, 10, 10, 50};

        for (int w = 0; w < KINDS; w++)
                best[w] = INFINITY;
        for (int k = 0; k < ROUNDS; k++)
                for (int w = 0; w < KINDS; w++) {
                        llref_threads(w == HORUS1 || w == TUNED1 ? 1 : 0);
                        double t0 = now_ms();
                        for (int i = 0; i < frames[w]; i++)
                                run(t, w);
                        best[w] = fmin(best[w], (now_ms() - t0) / frames[w]);
                }
}

/* The RMS (px) of reference `kind`'s centres against the analytic line; prints its misses
 * and spurious points. */
static double ref_rms(const struct llscene *s, struct timed *t, int kind, const char *name)
{
        struct laserline_result r = {.centre = t->ref_centre, .n = H};
        int visible, missed, spurious;
        double rms;

        run(t, kind);
        rms = ll_score(s, &r, &visible, &missed, &spurious);
        printf("%s reference: %d of the %d rows with the line missed, %d spurious points, RMS "
               "%.4f px\n",
               name, missed, visible, spurious, rms);
        return rms;
}

/* Prints the times, their ratios and our accuracy (r: our last centres); last the JSON line. */
static void report(const struct llscene *s, const struct laserline_result *r, const double b[KINDS])
{
        int visible, missed, spurious;
        double rms = ll_score(s, r, &visible, &missed, &spurious);

        printf("laserline: %dx%d RGB8, on minus off: ours %.3f ms/frame on two threads (a half "
               "of the rows each), %.3f ms on one; reading both frames (one thread) %.3f ms: ours "
               "on one thread %.2fx that\n",
               W, H, b[OURS2], b[OURS], b[MEMREAD], b[OURS] / b[MEMREAD]);
        printf("Horus port reference: %.3f ms with OpenCV's threads (%.1fx ours on two), %.3f ms "
               "on one thread (%.1fx ours on one)\n",
               b[HORUS], b[HORUS] / b[OURS2], b[HORUS1], b[HORUS1] / b[OURS]);
        printf("tuned OpenCV reference: %.3f ms with OpenCV's threads (%.1fx ours on two), %.3f ms "
               "on one thread (%.1fx ours on one)\n",
               b[TUNED], b[TUNED] / b[OURS2], b[TUNED1], b[TUNED1] / b[OURS]);
        printf("accuracy: %d rows with the line seen, %d missed, %d spurious, RMS %.4f px\n",
               visible, missed, spurious, rms);
        printf("ours, the faster: %.3f ms, %.1fx the Horus port with OpenCV's threads, %.2fx "
               "reading both frames\n",
               fmin(b[OURS], b[OURS2]), b[HORUS] / fmin(b[OURS], b[OURS2]),
               fmin(b[OURS], b[OURS2]) / b[MEMREAD]);
        printf("{\"bench\":\"laserline\",\"ms_per_frame\":%.4f,\"reference_ms\":%.4f,"
               "\"memread_ms\":%.4f,\"rms_px\":%.4f}\n",
               fmin(b[OURS], b[OURS2]), b[HORUS], b[MEMREAD], rms);
}

int main(void)
{
        static float centre[H], strength[H], width[H], centre2[H];
        struct llscene s;
        struct gn_frame on, off;
        struct timed t = {.r = {.centre = centre, .strength = strength, .width = width, .n = H}};
        double b[KINDS];

        ll_open(&s, W, H, 1.2e3, 0);
        ll_render(&s, true, false, 8, 1, &on);
        ll_render(&s, false, false, 8, 2, &off);
        t.on = &on;
        t.off = &off;
        laserline_opts_default(&t.o, 0);
        t.ref = llref_new(W, H);
        CHECK(t.ref);
        halves(&t);
        CHECK(sem_init(&t.go, 0, 0) == 0 && sem_init(&t.done, 0, 0) == 0);
        CHECK(pthread_create(&t.worker, NULL, worker, &t) == 0);
        run(&t, OURS2);
        memcpy(centre2, centre, sizeof(centre));
        run(&t, OURS);
        CHECK(memcmp(centre2, centre, sizeof(centre)) == 0); /* the halves agree with the whole */
        ref_rms(&s, &t, HORUS, "Horus port");
        ref_rms(&s, &t, TUNED, "tuned OpenCV");
        time_all(&t, b);
        report(&s, &t.r, b);
        t.quit = true;
        sem_post(&t.go);
        pthread_join(t.worker, NULL);
        llref_free(t.ref);
        gn_frame_free_data(&on);
        gn_frame_free_data(&off);
        ll_close(&s);
        return 0;
}
