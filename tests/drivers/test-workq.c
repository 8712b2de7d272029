/* test-workq.c - the worker queue: execution order with urgent jobs, the bounded queue
 * (-EAGAIN, urgent reserve), completions on a real sd-event loop thread, completions on
 * the worker without a loop, and -ECANCELED for jobs dropped by workq_free(); in each case
 * a done no longer sees its own job in flight. */
#include <errno.h>
#include <pthread.h>
#include <semaphore.h>
#include <stdint.h>
#include <systemd/sd-event.h>
#include <time.h>

#include "common/cleanup.h"
#include "common/workq.h"
#include "tests/test.h"

#define MAX_EVENTS 16

struct rec {
        struct workq *q;
        sd_event *event;
        sem_t started, gate;
        pthread_t loop_thread;
        int ran[MAX_EVENTS], n_ran;      /* ids in execution order (worker) */
        int done_id[MAX_EVENTS], n_done; /* ids in completion order */
        int done_res[MAX_EVENTS];
        bool done_on_loop[MAX_EVENTS];
        size_t done_in_flight[MAX_EVENTS]; /* workq_in_flight() during each done */
        int expect_done;
        pthread_mutex_t lock;
};

struct item {
        struct rec *rec;
        int id;
};

static int job(void *userdata)
{
        struct item *it = userdata;

        pthread_mutex_lock(&it->rec->lock);
        it->rec->ran[it->rec->n_ran++] = it->id;
        pthread_mutex_unlock(&it->rec->lock);
        return it->id * 10;
}

/* Blocks the worker until the test opens the gate, so that later jobs queue up. */
static int gate_job(void *userdata)
{
        struct item *it = userdata;

        sem_post(&it->rec->started);
        sem_wait(&it->rec->gate);
        return job(userdata);
}

static void done(int result, void *userdata)
{
        struct item *it = userdata;
        struct rec *r = it->rec;
        size_t in_flight = r->q ? workq_in_flight(r->q) : 0; /* NULL: freed (free_from_done) */
        int k;

        pthread_mutex_lock(&r->lock);
        k = r->n_done++;
        r->done_in_flight[k] = in_flight;
        r->done_id[k] = it->id;
        r->done_res[k] = result;
        r->done_on_loop[k] = pthread_equal(pthread_self(), r->loop_thread);
        pthread_mutex_unlock(&r->lock);
        if (r->event && r->n_done == r->expect_done)
                sd_event_exit(r->event, 0);
}

static void rec_init(struct rec *r, sd_event *event)
{
        *r = (struct rec){.event = event, .loop_thread = pthread_self()};
        sem_init(&r->started, 0, 0);
        sem_init(&r->gate, 0, 0);
        pthread_mutex_init(&r->lock, NULL);
}

/* Each done saw its own job and those done before it out of the count of pushed jobs. */
static void check_done_in_flight(const struct rec *r, int pushed)
{
        for (int k = 0; k < r->n_done; k++)
                CHECK((int)r->done_in_flight[k] <= pushed - k - 1);
}

static int on_timeout(sd_event_source *s, uint64_t usec, void *userdata)
{
        fprintf(stderr, "timed out waiting for completions\n");
        exit(1);
}

/* Gate, then 3 normal and 2 urgent: urgent run first; the 5th normal gets -EAGAIN. */
static void test_loop_order(void)
{
        struct item items[7];
        sd_event *event = NULL;
        sd_event_source *timer = NULL;
        struct rec r;
        static const int want[] = {0, 4, 5, 1, 2, 3};

        CHECK_INT(sd_event_new(&event), 0);
        rec_init(&r, event);
        for (int i = 0; i < 7; i++)
                items[i] = (struct item){&r, i};
        CHECK_INT(workq_new(event, "test", 4, &r.q), 0);
        CHECK_INT(workq_push(r.q, gate_job, done, &items[0], false), 0);
        sem_wait(&r.started);
        for (int i = 1; i <= 3; i++)
                CHECK_INT(workq_push(r.q, job, done, &items[i], false), 0);
        CHECK_INT(workq_push(r.q, job, done, &items[6], false), -EAGAIN);
        CHECK_INT(workq_push(r.q, job, done, &items[4], true), 0);
        CHECK_INT(workq_push(r.q, job, done, &items[5], true), 0);
        CHECK_INT(workq_in_flight(r.q), 6);
        r.expect_done = 6;
        sem_post(&r.gate);

        CHECK_INT(sd_event_add_time_relative(event, &timer, CLOCK_MONOTONIC, 10 * 1000000ULL, 0,
                                             on_timeout, NULL),
                  0);
        CHECK_INT(sd_event_loop(event), 0);
        CHECK_INT(r.n_ran, 6);
        CHECK_INT(r.n_done, 6);
        for (int i = 0; i < 6; i++) {
                CHECK_INT(r.ran[i], want[i]);
                CHECK_INT(r.done_id[i], want[i]); /* completions in finishing order */
                CHECK_INT(r.done_res[i], want[i] * 10);
                CHECK(r.done_on_loop[i]);
        }
        CHECK_INT(workq_in_flight(r.q), 0);
        check_done_in_flight(&r, 6);
        CHECK(workq_free(r.q) == NULL);
        sd_event_source_unref(timer);
        sd_event_unref(event);
}

/* Without a loop, done runs on the worker right after the job. */
static void test_no_loop(void)
{
        struct item items[3];
        struct rec r;

        rec_init(&r, NULL);
        for (int i = 0; i < 3; i++)
                items[i] = (struct item){&r, i + 1};
        CHECK_INT(workq_new(NULL, "noloop", 8, &r.q), 0);
        for (int i = 0; i < 3; i++)
                CHECK_INT(workq_push(r.q, job, done, &items[i], false), 0);
        for (int tries = 0; tries < 1000 && workq_in_flight(r.q) > 0; tries++)
                nanosleep(&(struct timespec){.tv_nsec = 10 * 1000000L}, NULL);
        CHECK_INT(workq_in_flight(r.q), 0);
        CHECK_INT(r.n_done, 3);
        for (int i = 0; i < 3; i++) {
                CHECK_INT(r.done_id[i], i + 1);
                CHECK_INT(r.done_res[i], (i + 1) * 10);
                CHECK(!r.done_on_loop[i]);
        }
        check_done_in_flight(&r, 3);
        CHECK(workq_free(r.q) == NULL);
}

/* Holds the worker until workq_free() has begun: once the test has filled the queue,
 * pushes fail with -EAGAIN (nothing is added) until they fail with -ESHUTDOWN. */
static int hold_until_shutdown(void *userdata)
{
        struct item *it = userdata;
        int r;

        sem_post(&it->rec->started);
        sem_wait(&it->rec->gate); /* until the test has filled the queue */
        while ((r = workq_push(it->rec->q, job, NULL, NULL, true)) == -EAGAIN)
                nanosleep(&(struct timespec){.tv_nsec = 1000000L}, NULL);
        return r == -ESHUTDOWN ? 42 : -EBADMSG;
}

/* Full queue including the urgent reserve; free delivers the running job's result and
 * cancels the rest with -ECANCELED, on the freeing thread. */
static void test_free_cancels(void)
{
        struct item items[1 + 1 + WORKQ_URGENT_RESERVE];
        sd_event *event = NULL;
        struct rec r;
        int n = (int)ELEMENTSOF(items);

        CHECK_INT(sd_event_new(&event), 0);
        rec_init(&r, event);
        r.event = NULL; /* no sd_event_exit from done: the loop is never run here */
        for (int i = 0; i < n; i++)
                items[i] = (struct item){&r, i};
        CHECK_INT(workq_new(event, "cancel", 2, &r.q), 0);
        CHECK_INT(workq_push(r.q, hold_until_shutdown, done, &items[0], false), 0);
        sem_wait(&r.started);
        CHECK_INT(workq_push(r.q, job, done, &items[1], false), 0);
        CHECK_INT(workq_push(r.q, job, done, &items[1], false), -EAGAIN);
        for (int i = 2; i < n; i++)
                CHECK_INT(workq_push(r.q, job, done, &items[i], true), 0);
        CHECK_INT(workq_push(r.q, job, done, &items[0], true), -EAGAIN); /* reserve used up */
        sem_post(&r.gate);

        CHECK(workq_free(r.q) == NULL);
        CHECK_INT(r.n_ran, 0);
        CHECK_INT(r.n_done, n);
        CHECK_INT(r.done_id[0], 0);
        CHECK_INT(r.done_res[0], 42);
        for (int i = 1; i < n; i++) {
                CHECK_INT(r.done_res[i], -ECANCELED);
                CHECK(r.done_on_loop[i]);
        }
        check_done_in_flight(&r, n);
        sd_event_unref(event);
}

/* The done of the first finished job frees the queue (as a session that ends in its last
 * store's done closes its dataset): the other finished jobs are delivered by workq_free, each
 * once, and the queue's memory outlives the loop's round of completions. */
static void done_frees(int result, void *userdata)
{
        struct item *it = userdata;
        struct workq *q = it->rec->q;

        done(result, userdata);
        if (it->id == 0) {
                it->rec->q = NULL; /* workq_in_flight(NULL) in the nested dones */
                CHECK(workq_free(q) == NULL);
        }
}

static void test_free_from_done(void)
{
        struct item items[3];
        sd_event *event = NULL;
        sd_event_source *timer = NULL;
        struct rec r;

        CHECK_INT(sd_event_new(&event), 0);
        rec_init(&r, event);
        r.expect_done = 3;
        CHECK_INT(workq_new(event, "freedone", 4, &r.q), 0);
        for (int i = 0; i < 3; i++) {
                items[i] = (struct item){&r, i};
                CHECK_INT(workq_push(r.q, job, done_frees, &items[i], false), 0);
        }
        for (int i = 0; i < 1000 && r.n_ran < 3; i++) /* all finished before the loop runs */
                nanosleep(&(struct timespec){0, 1000000}, NULL);
        nanosleep(&(struct timespec){0, 20000000}, NULL);
        CHECK_INT(sd_event_add_time_relative(event, &timer, CLOCK_MONOTONIC, 10 * 1000000ULL, 0,
                                             on_timeout, NULL),
                  0);
        CHECK_INT(sd_event_loop(event), 0);
        CHECK_INT(r.n_done, 3);
        for (int i = 0; i < 3; i++)
                CHECK_INT(r.done_id[i], i);
        sd_event_source_unref(timer);
        sd_event_unref(event);
}

int main(void)
{
        CHECK_INT(workq_new(NULL, "bad", 0, &(struct workq *){NULL}), -EINVAL);
        test_loop_order();
        test_no_loop();
        test_free_cancels();
        test_free_from_done();
        return 0;
}
