/* laserline-ref.h - bench/laserline's reference: the laser line found with OpenCV the usual
 * way (red channel, on minus off, threshold, blur, per row the brightest pixel and the
 * centre of mass in a window around it), as desktop scanners do. */
#pragma once

#include "common/frame.h"

#ifdef __cplusplus
extern "C" {
#endif

struct llref;

/* A reference extractor for w x h RGB8 frames; NULL on failure. */
struct llref *llref_new(int w, int h);

/* NULL is a no-op; returns NULL. */
struct llref *llref_free(struct llref *r);

/* Sets the number of threads OpenCV uses (cv::setNumThreads; 0 = its default). */
void llref_threads(int n);

/* centre[h]: per row, the centre (NAN: nothing above the threshold). Returns 0 or -EIO. */
int llref_extract(struct llref *r, const struct gn_frame *on, const struct gn_frame *off,
                  float *centre);

#ifdef __cplusplus
}
#endif
