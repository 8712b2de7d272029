/* sortx.h - the comparisons of qsort for plain numbers, and the median, shared so that no
 * module keeps its own copy. */
#pragma once

#include <stddef.h>

/* qsort comparison of two doubles, ascending (NaNs compare equal to everything). */
int gn_cmp_double(const void *a, const void *b);

/* qsort comparison of two floats, ascending. */
int gn_cmp_float(const void *a, const void *b);

/* Sorts v (n values) and returns its median (the mean of the middle two for even n); 0
 * when n is 0. */
double gn_median(double *v, size_t n);
