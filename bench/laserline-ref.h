/* laserline-ref.h - bench/laserline's references: the laser line found with OpenCV the way
 * desktop scanners do it. LLREF_HORUS ports, step for step and with its default settings,
 * what the Horus scanner (bq/horus 0.2, laser_segmentation.py and image_capture.py) does per
 * frame; LLREF_TUNED is a leaner version of the same steps (our own, kept for comparison). */
#pragma once

#include "common/frame.h"

#ifdef __cplusplus
extern "C" {
#endif

struct llref;

enum llref_kind {
        /* on minus off on the colour image (saturating), split, red channel, threshold to
         * zero at 50, 5x5 box blur, threshold again, per row a mask of +-8 px around the
         * argmax applied with bitwise_and, centre of mass over the whole row with a
         * double-precision weight matrix, then a Gaussian (sigma 2 rows) over each run of
         * rows with a line (Horus's "SGF" refinement) */
        LLREF_HORUS,
        /* red channels of both frames, subtract, threshold at 20, 5x5 Gaussian blur, per row
         * the centre of mass +-8 px around the brightest pixel */
        LLREF_TUNED,
};

/* A reference extractor for w x h RGB8 frames; NULL on failure. */
struct llref *llref_new(int w, int h);

/* NULL is a no-op; returns NULL. */
struct llref *llref_free(struct llref *r);

/* Sets the number of threads OpenCV uses (cv::setNumThreads; 0 = its default). */
void llref_threads(int n);

/* centre[h]: per row, the centre (NAN: no line found). Returns 0 or -EIO. */
int llref_extract(struct llref *r, enum llref_kind kind, const struct gn_frame *on,
                  const struct gn_frame *off, float *centre);

#ifdef __cplusplus
}
#endif
