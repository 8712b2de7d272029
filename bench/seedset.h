/* seedset.h - the seed-scale synthetic dataset of the appearance benchmarks (bench/fit,
 * bench/brdffit): 76 views x 100 lights x 720x480 by default (4 cameras x 19 turntable
 * angles, 5 lamps x 20 light-arm angles), a glossy 250 mm sphere rendered by gonio-sim's
 * renderer, 8-bit, noise off, generated once and cached in
 * $XDG_CACHE_HOME/gonio/bench-fit-<shape> (else ~/.cache/gonio/...). */
#pragma once

#include "dataset/ds.h"

#define SEEDSET_LAMPS 5

struct seedset_opts {
        int cameras, turntable, arm; /* 1..4 cameras, views per camera, light-arm angles */
        char dir[4096];              /* the cache */
};

/* Reads --turntable N (views per camera: fewer for a smaller run), --arm N, --cameras N and
 * --dir DIR into o (defaults above). Exits with status 2 on a bad option. */
void seedset_parse(int argc, char **argv, struct seedset_opts *o);

/* Opens o's dataset into *d, generating it first when it is not cached. Exits on failure. */
void seedset_open(const struct seedset_opts *o, struct ds **d);

/* Seconds to read and decode every image of d on 2 threads (nothing kept): the floor of
 * any fit that reads them. */
double seedset_decode_all(struct ds *d);

/* Says what failed (r: an errno, either sign) on stderr and exits with status 1. */
_Noreturn void seedset_die(const char *what, int r);
