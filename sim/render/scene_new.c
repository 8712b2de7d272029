/* scene_new.c - scene lifetime: parse the scene section, build the Embree device and
 * BVH from the placed geometries, tabulate the camera rays; and tear it all down. */
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "common/log.h"
#include "internal.h"

static void embree_error(void *user, enum RTCError code, const char *str)
{
        log_error("embree: error %d: %s", (int)code, str ? str : "");
}

static int attach(struct sim_scene *s, const struct rgeom *g, unsigned id)
{
        RTCGeometry geo;

        if (g->kind == GEOM_SPHERE) {
                float *v;
                geo = rtcNewGeometry(s->dev, RTC_GEOMETRY_TYPE_SPHERE_POINT);
                if (!geo)
                        return -ENOMEM;
                v = rtcSetNewGeometryBuffer(geo, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT4,
                                            4 * sizeof(float), 1);
                if (!v) {
                        rtcReleaseGeometry(geo);
                        return -ENOMEM;
                }
                memcpy(v, g->centre, 3 * sizeof(float));
                v[3] = g->radius;
        } else {
                geo = rtcNewGeometry(s->dev, RTC_GEOMETRY_TYPE_TRIANGLE);
                if (!geo)
                        return -ENOMEM;
                rtcSetSharedGeometryBuffer(geo, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                           g->mesh.pos, 0, 3 * sizeof(float), g->mesh.nv);
                rtcSetSharedGeometryBuffer(geo, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                           g->mesh.idx, 0, 3 * sizeof(uint32_t), g->mesh.nt);
        }
        rtcCommitGeometry(geo);
        rtcAttachGeometryByID(s->scn, geo, id);
        rtcReleaseGeometry(geo);
        return 0;
}

static int build_bvh(struct sim_scene *s)
{
        int r;

        s->dev = rtcNewDevice(NULL);
        if (!s->dev)
                return -ENODEV;
        rtcSetDeviceErrorFunction(s->dev, embree_error, NULL);
        s->scn = rtcNewScene(s->dev);
        if (!s->scn)
                return -ENOMEM;
        rtcSetSceneBuildQuality(s->scn, RTC_BUILD_QUALITY_HIGH);
        for (int i = 0; i < s->n_geoms; i++)
                if ((r = attach(s, &s->geoms[i], (unsigned)i)) < 0)
                        return r;
        rtcCommitScene(s->scn);
        return rtcGetDeviceError(s->dev) == RTC_ERROR_NONE ? 0 : -EIO;
}

static int default_threads(void)
{
        long n = sysconf(_SC_NPROCESSORS_ONLN);

        return n < 1 ? 1 : n > 16 ? 16 : (int)n;
}

int sim_scene_new(struct rig_config *rc, struct sim_scene **ret, char *err, size_t errlen)
{
        struct sim_scene *s;
        int r;

        if (!rc || !ret)
                return -EINVAL;
        if (err && errlen)
                err[0] = 0;
        s = calloc(1, sizeof(*s));
        if (!s)
                return -ENOMEM;
        s->rc = rc;
        r = scene_parse(s, err, errlen);
        for (size_t i = 0; r >= 0 && i < rc->n_cameras; i++)
                if ((r = camera_build(&s->cams[i], &rc->cameras[i])) < 0)
                        snprintf(err, errlen, "%s: camera '%s': bad intrinsics", rc->path,
                                 rc->cameras[i].name);
        if (r >= 0)
                r = sensor_table(&s->noise_q);
        if (r >= 0 && (r = build_bvh(s)) < 0)
                snprintf(err, errlen, "%s: cannot build the ray-tracing scene", rc->path);
        if (r < 0) {
                sim_scene_free(s);
                return r;
        }
        if (!s->threads)
                s->threads = default_threads();
        *ret = s;
        return 0;
}

struct sim_scene *sim_scene_free(struct sim_scene *s)
{
        if (!s)
                return NULL;
        if (s->scn)
                rtcReleaseScene(s->scn);
        if (s->dev)
                rtcReleaseDevice(s->dev);
        for (int i = 0; i < s->n_geoms; i++)
                mesh_free(&s->geoms[i].mesh);
        for (int i = 0; i < s->n_mats; i++)
                rmat_free(&s->mats[i]);
        for (size_t i = 0; i < RIG_MAX_CAMERAS; i++)
                camera_free(&s->cams[i]);
        free(s->dome_els);
        rtex_free(s->dome.env);
        free(s->noise_q);
        free(s);
        return NULL;
}
