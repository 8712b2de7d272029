/* output.h - what gonioctl prints: a result as one line of JSON (--json) or as aligned
 * human text (positions with 3 decimals), notifications for `watch`, the progress line
 * on a terminal, and error messages. Results go to stdout; errors and progress to stderr. */
#pragma once

#include <stdbool.h>

#include <jansson.h>

struct out {
        bool json;           /* --json: results and notifications as compact JSON lines */
        bool quiet;          /* --quiet: no result output, no progress */
        bool progress;       /* show a progress line (stderr is a terminal, human output) */
        bool progress_shown; /* a progress line is on screen */
        /* for the error object of --json (out_error_object) */
        bool error_printed;   /* an error object is on stdout already */
        int rpc_code;         /* goniod's JSON-RPC error code of the failure, 0: none */
        char error[512];      /* the first message out_error printed, "" if none */
        json_t *error_detail; /* more members of the error object (owned), or NULL */
};

/* Prints a result in human form; result is borrowed. */
typedef void (*out_print_fn)(json_t *result);

/* Fills o for the given flags, checking whether stderr is a terminal. */
void out_init(struct out *o, bool json, bool quiet);

/* Prints result (borrowed): compact JSON on one line with --json, else human(result) or,
 * when human is NULL, the line text (if not NULL); nothing with --quiet. Clears the
 * progress line first. */
void out_result(struct out *o, out_print_fn human, const char *text, json_t *result);

/* Prints "gonioctl: <what>: <message>" (only "<message>" when what is NULL) to stderr, after
 * clearing the progress line; the first message is kept for out_error_object. */
void out_error(struct out *o, const char *what, const char *fmt, ...)
        __attribute__((format(printf, 3, 4)));

/* With --json, unless one was printed already, prints {"error":{"code":code,"exit":exit_code,
 * "message":...}} on stdout: the message the first out_error printed (else fallback, may be
 * NULL), "rpc_code" when goniod reported the error, and the members of o->error_detail. */
void out_error_object(struct out *o, const char *code, int exit_code, const char *fallback);

/* Frees what o holds (o->error_detail). */
void out_done(struct out *o);

/* Shows a notification on the progress line (terminal only); params may be NULL. */
void out_progress(struct out *o, const char *method, json_t *params);

/* Erases the progress line if one is shown. */
void out_progress_end(struct out *o);

/* Prints a notification for `watch`: {"method":..,"params":..} with --json, else a
 * time-stamped "method key=value ..." line. Flushes stdout. */
void out_notification(struct out *o, const char *method, json_t *params);

/* Human printers, one per result shape of docs/protocol.md. */
void out_print_status(json_t *r);
void out_print_describe(json_t *r);
void out_print_home(json_t *r);
void out_print_move(json_t *r);
void out_print_stop(json_t *r);
void out_print_lamp(json_t *r);
void out_print_laser(json_t *r);
void out_print_capture(json_t *r);
void out_print_dataset(json_t *r);
void out_print_dataset_list(json_t *r);
void out_print_dataset_info(json_t *r);
void out_print_pretty(json_t *r); /* indented JSON, for `call` */
void out_print_devices(json_t *r);
