/* gpiod.h - gonio's one wrapper of libgpiod 1.6 (Debian 12), shaped like libgpiod 2's line
 * requests so that moving to v2 changes only gpiod.c: a request holds several lines of one
 * chip with their settings, values are read and written through the request, and edge events
 * of all its inputs come through one fd the caller polls (v2's gpiod_line_request_get_fd).
 * Lines are named by index into the settings they were requested with (v2 uses offsets).
 * Used by the "gpio" axis (drivers/axis/gpio/) and "gpio" switch (drivers/switch/gpio/)
 * backends; nothing else includes <gpiod.h>.
 *
 * A chip can vanish under an open request (a USB GPIO expander unplugged, gpio-sim's `live`
 * set to 0): the kernel then answers every operation of the request with ENODEV and never
 * again otherwise. The request remembers it (gpio_request_lost()), answers -ENODEV from then
 * on without asking the kernel, and gpio_request_reopen() requests the same lines again once
 * the chip is back, found by the name or label it was opened with. */
#pragma once

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/* Longest cause written into a caller's err buffer. */
#define GPIO_ERR_MAX 160

enum gpio_direction { GPIO_INPUT, GPIO_OUTPUT };

/* How one line of a request is configured. Values are logical: with active_low, 1 is a low
 * level on the pin. */
struct gpio_line_settings {
        const char *line; /* offset ("3") or line name ("home"); borrowed during the call */
        enum gpio_direction direction;
        bool active_low;
        bool edge_events; /* inputs: report both edges through gpio_request_fd() */
        int output_value; /* outputs: initial value, 0 or 1 */
};

/* An edge seen on an input requested with edge_events. */
struct gpio_edge_event {
        size_t index; /* into the settings of the request */
        bool rising;  /* as the kernel reports it (physical for libgpiod 1.6) */
        uint64_t timestamp_ns;
};

struct gpio_request;

/* Opens chip (a name "gpiochip0", a path, a number or a label "gonio-gpio") and requests the n
 * lines of settings for consumer. Returns 0 and *ret (free with gpio_request_release()), or
 * -errno with the cause in err ("no line named 'stepx' on gpiochip1 [gonio-gpio]", "line 3 of
 * gpiochip1 [gonio-gpio]: Device or resource busy"): -ENOENT for an unknown chip or line,
 * -EBUSY for a line another consumer holds. */
int gpio_request_lines(const char *chip, const char *consumer,
                       const struct gpio_line_settings *settings, size_t n,
                       struct gpio_request **ret, char *err, size_t errlen);

/* Whether the chip of r has vanished (an operation got ENODEV); false for NULL. Any thread. */
bool gpio_request_lost(const struct gpio_request *r);

/* Requests the lines of *r again, as gpio_request_lines() did, when its chip was lost: the
 * chip is looked up anew by the name or label it was opened with (it may come back as another
 * gpiochipN), and the new request replaces *r (the old one is released). Returns 0 (also
 * when *r was not lost: nothing done), -ENODEV while the chip is still gone (*r kept), or
 * -errno of gpio_request_lines() with the cause in err. */
int gpio_request_reopen(struct gpio_request **r, char *err, size_t errlen);

/* When r's chip is lost, writes "GPIO chip 'gonio-gpio' (gpiochip1) is gone (unplugged?)
 * while WHAT; fault.clear reopens it once it is back" into buf and returns buf; else NULL. */
const char *gpio_request_lost_cause(const struct gpio_request *r, const char *what, char *buf,
                                    size_t len);

/* Releases the lines and closes the chip; NULL is a no-op. Returns NULL. */
struct gpio_request *gpio_request_release(struct gpio_request *r);

/* The logical value (0 or 1) of line index, input or output, or -errno (-ENODEV: lost). */
int gpio_request_get_value(struct gpio_request *r, size_t index);

/* Sets output line index to value (0 or 1). Returns 0 or -errno (-ENODEV: lost). */
int gpio_request_set_value(struct gpio_request *r, size_t index, int value);

/* An fd that polls readable while edge events are pending, valid until release; -EBADF
 * when the request has no line with edge_events. */
int gpio_request_fd(const struct gpio_request *r);

/* Reads up to max pending edge events without blocking. Returns how many (0: none), or
 * -errno (-ENODEV: lost; the fd then polls readable for good). */
int gpio_request_read_edge_events(struct gpio_request *r, struct gpio_edge_event *ev, size_t max);

/* "gpiochip1 [gonio-gpio]": the chip's name and label, for messages. */
const char *gpio_request_chip(const struct gpio_request *r);
