/* switch.h - the switch device class: lamps, the laser, spare outputs.
 *
 * Ops are blocking and run on the switch's bus worker. The cached state changes
 * only after the device has confirmed the write (read back). */
#pragma once

#include <stdbool.h>

#include "common/rigconf.h"
#include "drivers/bus/bus.h"
#include "drivers/opt.h"

struct bus;
struct sw;

struct sw_ops {
        const char *name; /* backend name in the rig file */
        const struct opt_desc *opts;
        int n_opts;
        int (*open)(struct sw *s);
        void (*close)(struct sw *s);
        int (*set)(struct sw *s, bool on);
        int (*get)(struct sw *s, bool *on);
};

struct sw {
        const struct sw_ops *ops;
        const struct rig_switch_conf *conf; /* borrowed */
        struct bus *bus;                    /* borrowed */
        void *priv;
        bool on; /* last confirmed state */
        /* The last message the class logged at warning level or worse, whole, for
         * operators; "" when none. Written by the ops' thread (see axis.h). */
        char last_error[DEV_ERROR_MAX];
        char cause[DEV_ERROR_MAX]; /* detail of the op in progress, see sw_set_cause() */
};

/* Creates the switch for conf (drivers/registry.c). Returns 0, -ENOENT or -errno. No I/O. */
int sw_new(const struct rig_switch_conf *conf, struct bus *bus, struct sw **ret);

/* Closes and frees; NULL is a no-op. Returns NULL. */
struct sw *sw_free(struct sw *s);

/* Open/set/get wrappers that log "switch 'NAME' [...]: Failed to OPERATION: CAUSE" on
 * failure (CAUSE from sw_set_cause(), else strerror), also kept in s->last_error;
 * 0 or -errno. */
int sw_open(struct sw *s);
int sw_set(struct sw *s, bool on); /* writes, reads back, updates s->on, waits warmup_ms if on */
int sw_get(struct sw *s, bool *on);

/* Logs "switch 'NAME' [BACKEND@PORT#UNIT]: message" at level (GN_LOG_*); %m prints err.
 * Returns -abs(err). At warning level or worse also fills last_error: the ops' thread. */
int sw_log_full(struct sw *s, int level, int err, const char *fmt, ...)
        __attribute__((format(printf, 4, 5)));

/* For backends: records the detail of the current op's failure without logging (see
 * axis_set_cause()). Returns -abs(err). */
int sw_set_cause(struct sw *s, int err, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
