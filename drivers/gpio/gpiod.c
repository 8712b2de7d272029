/* gpiod.c - the v2-shaped line requests of gpiod.h over libgpiod 1.6: one gpiod_chip per
 * request, one gpiod_line per setting, and an epoll fd gathering the event fds of the
 * inputs requested with edge events (libgpiod 1.6 has one fd per line, v2 one per request).
 * A request keeps copies of its settings so that it can be made again on a chip that came
 * back after it vanished. */
#include <errno.h>
#include <stdatomic.h>
#include <gpiod.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/epoll.h>
#include <unistd.h>

#include "common/cleanup.h"
#include "drivers/gpio/gpiod.h"

struct gpio_request {
        struct gpiod_chip *chip; /* NULL until opened */
        struct gpiod_line **lines;
        struct gpio_line_settings *settings; /* copies (lines too), to request them again */
        size_t n;
        int epfd; /* -EBADF without edge events */
        atomic_bool lost;
        char *spec, *consumer; /* as the caller named the chip and itself */
        char chip_desc[96];
};

struct gpio_request *gpio_request_release(struct gpio_request *r)
{
        if (!r)
                return NULL;
        if (r->epfd >= 0)
                close(r->epfd);
        if (r->chip)
                gpiod_chip_close(r->chip); /* releases the lines */
        for (size_t i = 0; r->settings && i < r->n; i++)
                free((char *)r->settings[i].line);
        free(r->settings);
        free(r->lines);
        free(r->spec);
        free(r->consumer);
        free(r);
        return NULL;
}

DEFINE_TRIVIAL_CLEANUP_FUNC(struct gpio_request *, gpio_request_release);

/* The line named spec on r's chip: all digits is an offset, anything else a line name. */
static int find_line(struct gpio_request *r, const char *spec, struct gpiod_line **ret, char *err,
                     size_t errlen)
{
        char *end;
        unsigned long off;

        if (!spec || !spec[0])
                return snprintf(err, errlen, "empty line name"), -EINVAL;
        errno = 0;
        off = strtoul(spec, &end, 10);
        if (*end == '\0' && spec[0] >= '0' && spec[0] <= '9') {
                if (errno || off >= gpiod_chip_num_lines(r->chip))
                        return snprintf(err, errlen, "%s has no line %s (%u lines)", r->chip_desc,
                                        spec, gpiod_chip_num_lines(r->chip)),
                               -ENOENT;
                *ret = gpiod_chip_get_line(r->chip, (unsigned)off);
        } else
                *ret = gpiod_chip_find_line(r->chip, spec);
        if (!*ret)
                return snprintf(err, errlen, "no line named '%s' on %s", spec, r->chip_desc),
                       errno == ENOENT || errno == 0 ? -ENOENT : -errno;
        return 0;
}

/* Requests one line as s says and adds its event fd to the epoll set. */
static int request_one(struct gpio_request *r, size_t i, const struct gpio_line_settings *s,
                       const char *consumer, char *err, size_t errlen)
{
        struct gpiod_line_request_config cfg = {.consumer = consumer};
        struct epoll_event ev = {.events = EPOLLIN, .data.u64 = i};
        int k;

        k = find_line(r, s->line, &r->lines[i], err, errlen);
        if (k < 0)
                return k;
        cfg.request_type = s->direction == GPIO_OUTPUT ? GPIOD_LINE_REQUEST_DIRECTION_OUTPUT
                           : s->edge_events            ? GPIOD_LINE_REQUEST_EVENT_BOTH_EDGES
                                                       : GPIOD_LINE_REQUEST_DIRECTION_INPUT;
        cfg.flags = s->active_low ? GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW : 0;
        if (gpiod_line_request(r->lines[i], &cfg, s->output_value) < 0) {
                k = -errno;
                snprintf(err, errlen, "line %s of %s: %s", s->line, r->chip_desc, strerror(-k));
                return k;
        }
        if (s->direction == GPIO_OUTPUT || !s->edge_events)
                return 0;
        if (r->epfd < 0 && (r->epfd = epoll_create1(EPOLL_CLOEXEC)) < 0)
                return snprintf(err, errlen, "epoll: %m"), -errno;
        if (epoll_ctl(r->epfd, EPOLL_CTL_ADD, gpiod_line_event_get_fd(r->lines[i]), &ev) < 0)
                return snprintf(err, errlen, "epoll: %m"), -errno;
        return 0;
}

/* A request of the n lines of settings on chip, not open yet: copies of what it was asked. */
static int request_new(const char *chip, const char *consumer,
                       const struct gpio_line_settings *settings, size_t n,
                       struct gpio_request **ret)
{
        _cleanup_(gpio_request_releasep) struct gpio_request *r = calloc(1, sizeof(*r));

        if (!r)
                return -ENOMEM;
        r->epfd = -EBADF;
        r->lines = calloc(n, sizeof(*r->lines));
        r->settings = calloc(n, sizeof(*r->settings));
        r->spec = strdup(chip);
        r->consumer = strdup(consumer);
        if (!r->lines || !r->settings || !r->spec || !r->consumer)
                return -ENOMEM;
        for (; r->n < n; r->n++) {
                r->settings[r->n] = settings[r->n];
                r->settings[r->n].line = settings[r->n].line ? strdup(settings[r->n].line) : NULL;
                if (settings[r->n].line && !r->settings[r->n].line)
                        return -ENOMEM;
        }
        *ret = TAKE_PTR(r);
        return 0;
}

/* Opens r's chip by its spec and requests its lines. */
static int request_all(struct gpio_request *r, char *err, size_t errlen)
{
        int k;

        r->chip = gpiod_chip_open_lookup(r->spec);
        if (!r->chip) {
                k = errno ? -errno : -ENOENT;
                snprintf(err, errlen, "cannot open GPIO chip '%s': %s", r->spec, strerror(-k));
                return k;
        }
        snprintf(r->chip_desc, sizeof(r->chip_desc), "%s [%s]", gpiod_chip_name(r->chip),
                 gpiod_chip_label(r->chip));
        for (size_t i = 0; i < r->n; i++) {
                k = request_one(r, i, &r->settings[i], r->consumer, err, errlen);
                if (k < 0)
                        return k;
        }
        return 0;
}

int gpio_request_lines(const char *chip, const char *consumer,
                       const struct gpio_line_settings *settings, size_t n,
                       struct gpio_request **ret, char *err, size_t errlen)
{
        _cleanup_(gpio_request_releasep) struct gpio_request *r = NULL;
        int k;

        if (!chip || !consumer || !settings || !ret || n == 0)
                return -EINVAL;
        k = request_new(chip, consumer, settings, n, &r);
        if (k < 0)
                return k;
        k = request_all(r, err, errlen);
        if (k < 0)
                return k;
        *ret = TAKE_PTR(r);
        return 0;
}

bool gpio_request_lost(const struct gpio_request *r)
{
        return r && atomic_load(&r->lost);
}

int gpio_request_reopen(struct gpio_request **r, char *err, size_t errlen)
{
        _cleanup_(gpio_request_releasep) struct gpio_request *n = NULL;
        int k;

        if (!r || !*r)
                return -EINVAL;
        if (!gpio_request_lost(*r))
                return 0;
        k = request_new((*r)->spec, (*r)->consumer, (*r)->settings, (*r)->n, &n);
        if (k < 0)
                return k;
        k = request_all(n, err, errlen);
        if (k < 0 && !n->chip)
                return snprintf(err, errlen, "GPIO chip '%s' is still gone (unplugged?)",
                                (*r)->spec),
                       -ENODEV;
        if (k < 0)
                return k;
        gpio_request_release(*r);
        *r = TAKE_PTR(n);
        return 0;
}

const char *gpio_request_lost_cause(const struct gpio_request *r, const char *what, char *buf,
                                    size_t len)
{
        if (!gpio_request_lost(r))
                return NULL;
        snprintf(buf, len,
                 "GPIO chip '%s' (%s) is gone (unplugged?) while %s; fault.clear reopens it "
                 "once it is back",
                 r->spec, gpiod_chip_name(r->chip), what);
        return buf;
}

/* -errno of a failed libgpiod call on r; ENODEV marks r lost (its chip vanished). */
static int failed(struct gpio_request *r)
{
        int k = errno ? -errno : -EIO;

        if (k == -ENODEV)
                atomic_store(&r->lost, true);
        return k;
}

int gpio_request_get_value(struct gpio_request *r, size_t index)
{
        int v;

        if (!r || index >= r->n)
                return -EINVAL;
        if (gpio_request_lost(r))
                return -ENODEV;
        v = gpiod_line_get_value(r->lines[index]);
        return v < 0 ? failed(r) : v;
}

int gpio_request_set_value(struct gpio_request *r, size_t index, int value)
{
        if (!r || index >= r->n)
                return -EINVAL;
        if (gpio_request_lost(r))
                return -ENODEV;
        return gpiod_line_set_value(r->lines[index], !!value) < 0 ? failed(r) : 0;
}

int gpio_request_fd(const struct gpio_request *r)
{
        return r ? r->epfd : -EBADF;
}

int gpio_request_read_edge_events(struct gpio_request *r, struct gpio_edge_event *ev, size_t max)
{
        struct epoll_event ready[8];
        struct gpiod_line_event le;
        int n, got = 0;

        if (!r || r->epfd < 0)
                return -EBADF;
        if (gpio_request_lost(r))
                return -ENODEV;
        n = epoll_wait(r->epfd, ready, (int)MIN(max, ELEMENTSOF(ready)), 0);
        if (n < 0)
                return -errno;
        for (int i = 0; i < n; i++) {
                size_t idx = (size_t)ready[i].data.u64;

                if (gpiod_line_event_read(r->lines[idx], &le) < 0)
                        return failed(r);
                ev[got++] = (struct gpio_edge_event){
                        .index = idx,
                        .rising = le.event_type == GPIOD_LINE_EVENT_RISING_EDGE,
                        .timestamp_ns = (uint64_t)le.ts.tv_sec * 1000000000u + le.ts.tv_nsec,
                };
        }
        return got;
}

const char *gpio_request_chip(const struct gpio_request *r)
{
        return r ? r->chip_desc : "";
}
