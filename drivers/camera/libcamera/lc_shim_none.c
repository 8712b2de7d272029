/* lc_shim_none.c - lc_shim.h where gonio is built without libcamera (-Dlibcamera=disabled
 * or not found): a rig file naming a libcamera camera still loads, opening the camera
 * fails with -EOPNOTSUPP and a cause that says why, and listing cameras fails the same way. */
#include <errno.h>
#include <stdio.h>

#include "drivers/camera/libcamera/lc_shim.h"

/* Fails like lc_cam_open(), with the same cause. */
static int no_libcamera(char *cause, size_t len)
{
        snprintf(cause, len, "gonio was built without libcamera");
        return -EOPNOTSUPP;
}

int lc_cam_open(const char *id, const char *model, int index, int width, int height,
                const uint32_t *fourccs, size_t n, struct lc_cam **ret, char *cause, size_t len)
{
        return no_libcamera(cause, len);
}

int lc_list(void (*fn)(const struct lc_camera_info *info, void *data), void *data, char *cause,
            size_t len)
{
        return no_libcamera(cause, len);
}

/* Never reached without a camera; defined for the linker. */
void lc_cam_close(struct lc_cam *cam)
{
}

const char *lc_cam_id(const struct lc_cam *cam)
{
        return "";
}

void lc_cam_caps(const struct lc_cam *cam, struct lc_caps *caps)
{
        *caps = (struct lc_caps){0};
}

int lc_cam_start(struct lc_cam *cam, int exposure_us, double gain, char *cause, size_t len)
{
        return -EOPNOTSUPP;
}

int lc_cam_fd(const struct lc_cam *cam)
{
        return -EOPNOTSUPP;
}

int lc_cam_next(struct lc_cam *cam, struct lc_frame *out, char *cause, size_t len)
{
        return -EOPNOTSUPP;
}

void lc_cam_stop(struct lc_cam *cam)
{
}
