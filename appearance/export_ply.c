/* export_ply.c - the scan as PLY files that Open3D, MeshLab and CloudCompare read (export.h,
 * docs/exports.md): points.ply (the cloud: x y z nx ny nz red green blue) and mesh.ply (the
 * simplified mesh with the same vertex properties and its faces), binary little-endian, in
 * the object frame (mm), copied from the dataset's scan (calib/scan.h). A dataset without a
 * scan is refused (-ENOENT); one of the two files missing is left out. */
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "appearance/export_internal.h"
#include "calib/scan.h"
#include "common/fileio.h"

#define PLY_MAX_BYTES (1ul << 31)

/* Copies ds_dir/from to dir/to. Returns 0, -ENOENT or -errno with a sentence in err. */
static int copy_file(const char *ds_dir, const char *from, const char *dir, const char *to,
                     char *err, size_t errlen)
{
        _cleanup_free_ void *buf = NULL;
        char src[4200], dst[4200];
        size_t len;
        int r;

        snprintf(src, sizeof(src), "%s/%s", ds_dir, from);
        snprintf(dst, sizeof(dst), "%s/%s", dir, to);
        r = gn_read_file_at(AT_FDCWD, src, PLY_MAX_BYTES, &buf, &len);
        if (r == 0 && (r = gn_write_atomic(AT_FDCWD, dst, buf, len, NULL)) < 0)
                snprintf(err, errlen, "cannot write %s: %s", dst, strerror(-r));
        else if (r < 0)
                snprintf(err, errlen, "%s: %s", src, strerror(-r));
        return r;
}

int ap_export_ply(struct ds *d, const char *ds_dir, const char *dir, const struct ap_export_opts *o,
                  char *err, size_t errlen)
{
        int rp, rm;

        (void)d, (void)o;
        rp = copy_file(ds_dir, SCAN_FILE_POINTS, dir, "points.ply", err, errlen);
        if (rp < 0 && rp != -ENOENT)
                return rp;
        rm = copy_file(ds_dir, SCAN_FILE_MESH_PLY, dir, "mesh.ply", err, errlen);
        if (rm < 0 && rm != -ENOENT)
                return rm;
        if (rp == -ENOENT && rm == -ENOENT) {
                snprintf(err, errlen,
                         "%s has no scan (%s, %s): capture one with gonioctl scan first", ds_dir,
                         SCAN_FILE_POINTS, SCAN_FILE_MESH_PLY);
                return -ENOENT;
        }
        return 0;
}
