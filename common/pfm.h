/* pfm.h - the Portable Float Map (PFM) image format, as HDR environment maps come: a
 * three-line text header ("PF" RGB or "Pf" grey; width height; scale, negative for
 * little-endian), then float rows bottom first. One reader for appearance/ and sim/. */
#pragma once

#include <stddef.h>
#include <stdint.h>

/* Decodes the PFM in buf (len bytes) into a malloc'ed linear RGB float image (*rgb, 3 per
 * pixel, rows top first, grey copied to the three channels, non-finite samples as 0) of
 * *w x *h. Returns 0, -EBADMSG (not a PFM, truncated, a side outside 1..max_side) or
 * -ENOMEM; *rgb is untouched on failure. */
int gn_pfm_decode(const uint8_t *buf, size_t len, int max_side, float **rgb, int *w, int *h);

/* Encodes the linear RGB float image rgb (3 per pixel, rows top first) of w x h as a
 * little-endian "PF" file into *buf (malloc'ed, *len bytes). Returns 0, -EINVAL (a side
 * below 1) or -ENOMEM. */
int gn_pfm_encode(const float *rgb, int w, int h, void **buf, size_t *len);
