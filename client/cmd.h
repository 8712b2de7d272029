/* cmd.h - gonioctl's subcommands: one table naming each command, its arguments, options,
 * JSON-RPC method, reply timeout and printer, and the runner that connects, says hello,
 * calls the method and maps the outcome to an exit code (docs/gonioctl.md). */
#pragma once

#include <stdio.h>

#include "client/args.h"
#include "client/conn.h"
#include "client/output.h"

/* gonioctl's exit codes. */
enum gonioctl_exit {
        EXIT_OK = 0,
        EXIT_USAGE = 2,        /* bad command line */
        EXIT_CONNECT = 3,      /* cannot connect to goniod */
        EXIT_PROTOCOL = 4,     /* protocol error, bad reply, timeout waiting, connection lost */
        EXIT_DEVICE = 5,       /* device fault or device timeout (-32003, -32004) */
        EXIT_INVALID = 6,      /* invalid params, not found, out of range, no such method */
        EXIT_STORAGE = 7,      /* storage error (-32006) */
        EXIT_CANCELED = 8,     /* canceled by stop (-32007) */
        EXIT_BUSY = 9,         /* busy or wrong state (-32001, -32008) */
        EXIT_INTERRUPTED = 10, /* Ctrl-C, SIGTERM or --timeout while waiting for move/home:
                                * gonioctl sent stop and goniod confirmed it; or wait ended
                                * by --timeout or a signal */
};

/* The exit code for a JSON-RPC error code from the server. */
int cmd_exit_for_code(int code);

/* The exit code of a local command (calibrate, scan --from) that failed with -errno r: what
 * the input lacks or holds wrongly is EXIT_INVALID, anything else (reading, writing)
 * EXIT_STORAGE. */
int cmd_exit_for_errno(int r);

/* Runs the command named by a->words. Returns an enum gonioctl_exit value; errors are
 * printed to stderr as "gonioctl: <method>: <message>", and with --json as an error object
 * {"error":{"code","exit","message",...}} on stdout. */
int cmd_run(const struct args *a);

/* After args_parse failed: prints the error object of the usage error (--json). Returns
 * EXIT_USAGE. */
int cmd_usage_failed(const struct args *a);

/* --help: the usage of gonioctl, of the command a->words name, or of a group of commands.
 * Returns EXIT_OK, or EXIT_USAGE for an unknown command (error printed). */
int cmd_help(const struct args *a);

struct conn;
struct out;

/* Where a reaches goniod over TCP ("HOST:PORT": --connect, else $GONIO_CONNECT unless
 * --socket is given), or NULL for its Unix socket. */
const char *cmd_tcp_address(const struct args *a);

/* Connects to goniod (cmd_tcp_address, else --socket, else the default path) and says hello
 * (with the token over TCP; checks the protocol version). Returns EXIT_OK with a new
 * connection in *ret, or the exit code (error printed). */
int cmd_connect(const struct args *a, struct out *o, struct conn **ret);

/* Catches SIGINT and SIGTERM from now on: returns a descriptor that becomes readable with one
 * byte per signal (its number), or -errno. */
int cmd_intr_fd(void);

struct conn_error;

/* Prints a failed call's error (r from conn_call, e its error) and returns the exit code. */
int cmd_call_failed(struct out *o, const char *method, int r, const struct conn_error *e);

/* Prints the usage text (generated from the command table) to f. */
void cmd_usage(FILE *f);
