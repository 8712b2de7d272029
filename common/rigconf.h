/* rigconf.h - the rig file: every device of a capture rig, its backend and
 * connection, its geometry and its limits (see docs/rig-file.md).
 *
 * Loaded once by goniod and by gonio-sim from the same YAML file. The parsed
 * struct is plain data; the YAML document stays open so that gonio-sim can read
 * the scene section through rigconf_scene().
 *
 * Each device entry holds its class's keys (name, limits, elevation...) and one map named
 * after its backend ("modbus: { bus: drives, unit: 1 }"). rigconf knows no backend: the
 * caller passes a table of them (struct rig_backend; goniod's is registry_backends in
 * drivers/registry.c), and each backend parses its own map at load time. */
#pragma once

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "pose.h"
#include "yconf.h"

#define RIG_NAME_MAX    32
#define RIG_PATH_MAX    256
#define RIG_MAX_BUSES   8
#define RIG_MAX_AXES    8
#define RIG_MAX_LAMPS   16
#define RIG_MAX_CAMERAS 8
#define RIG_MAX_LASERS  8 /* a pose's laser bit set holds GN_POSE_MAX_LASERS */

/* Ranges of a camera's default exposure and gain in the rig file: those of the sim camera's
 * option table (drivers/camera/sim/api.c), so that a rig file that loads never asks a camera
 * for a control its driver refuses. goniod's capture params (daemon/methods.c) still check
 * their own range; the camera option tables are to become the one source of these limits. */
#define RIG_EXPOSURE_US_MIN 1
#define RIG_EXPOSURE_US_MAX 10000000 /* 10 s */
#define RIG_GAIN_MIN        0.1
#define RIG_GAIN_MAX        64.0

enum rig_bus_type {
        RIG_BUS_MODBUS_RTU,
        RIG_BUS_MODBUS_TCP,
        RIG_BUS_SIM,    /* gonio-sim frame socket (Unix stream socket path in port) */
        RIG_BUS_SERIAL, /* a plain serial line (G-code controllers), port and line settings */
        RIG_BUS_LOCAL,  /* no line: a worker for devices their backend opens itself (V4L2 node,
                         * gpiochip, USB device, libcamera id) */
};

struct rig_bus_conf {
        char name[RIG_NAME_MAX];
        enum rig_bus_type type;
        char port[RIG_PATH_MAX]; /* serial device / socket path */
        char host[64];           /* modbus-tcp */
        int tcp_port;            /* modbus-tcp */
        int baud;                /* default 115200 */
        char parity;             /* 'N', 'E', 'O' */
        int data_bits, stop_bits;
        int timeout_ms; /* per request, default 200 */
        int retries;    /* extra attempts on timeout/CRC error, default 2 */
};

/* Register map of a Modbus axis drive (docs/modbus-profile.md). Addresses are
 * holding registers; 32-bit values span two registers, high word first unless
 * word_swap. Positions are in steps of 1/scale degree. */
struct rig_modbus_profile {
        char name[RIG_NAME_MAX];
        uint16_t reg_status;   /* bit field, see AXIS_ST_* in drivers/axis/modbus/proto.h */
        uint16_t reg_position; /* actual position, int32 */
        uint16_t reg_target;   /* target position, int32 */
        uint16_t reg_speed;    /* max speed, uint16 in 0.1 deg/s */
        uint16_t reg_accel;    /* acceleration, uint16 in 0.1 deg/s^2 */
        uint16_t reg_command;  /* command register */
        uint16_t reg_fault;    /* fault code */
        uint16_t cmd_move, cmd_home, cmd_stop, cmd_reset;
        double scale; /* position counts per degree, default 1000 */
        bool word_swap;
};

struct rig_config;

/* The device classes of the rig file. */
enum rig_class { RIG_CLASS_AXIS, RIG_CLASS_SWITCH, RIG_CLASS_CAMERA };

/* Where a device sits on its bus, as its backend says, for the checks across entries: two
 * devices of one bus clash when they have the same address, unless both have sub-addresses
 * and these differ (a drive takes a whole Modbus unit, a lamp one coil of a relay module).
 * The keys are those of the backend map, for messages. */
struct rig_addr {
        const char *key; /* "unit"; NULL: no address, never clashes */
        int value;
        const char *sub_key; /* "coil"; NULL: the device takes the whole address */
        int sub;
};

/* A device's backend, as read from its backend map. */
struct rig_backend_conf {
        char name[RIG_NAME_MAX]; /* the key naming the map: "modbus" */
        /* What the backend parsed from the map (struct mbax_conf for "modbus"), NULL for a
         * backend without settings beyond the bus or a conf built by hand; owned by the rig
         * config. */
        const void *conf;
        struct rig_addr addr;
};

/* A backend as the rig file knows it: one entry of the table given to rigconf_load(). */
struct rig_backend {
        const char *name; /* the key naming its map in a device entry: "modbus" */
        enum rig_class cls;
        unsigned bus_types; /* bit 1 << enum rig_bus_type for each kind of bus it runs on */
        size_t conf_size;   /* bytes of its parsed conf; 0: it has none (conf is NULL) */
        /* Parses the backend map m (its "bus" already read by rigconf) into conf
         * (conf_size zeroed bytes) and *addr. Rejects unknown keys and bad values with
         * yconf_error() (file, line, key). rc holds the buses and profiles read so far.
         * Returns 0 or -EINVAL. */
        int (*parse_conf)(struct yconf *yc, struct fy_node *m, const struct rig_config *rc,
                          void *conf, struct rig_addr *addr);
        const void *ops; /* the class's ops for drivers/ (struct axis_ops...), opaque here */
};

struct rig_axis_conf {
        char name[RIG_NAME_MAX];
        char bus[RIG_NAME_MAX]; /* from the backend map: every backend has a bus */
        struct rig_backend_conf backend;
        int role;                /* enum gn_role, or -1: moves nothing the pose records */
        bool continuous;         /* wraps at 360 deg; no soft limits */
        double min_deg, max_deg; /* soft limits (when !continuous) */
        double max_speed;        /* deg/s: the speed of moves, and the most `set` allows */
        double accel;            /* deg/s^2: the acceleration of moves */
        double max_accel;        /* deg/s^2: the most `set` allows (default: accel) */
        int settle_ms;           /* extra wait after in-position */
        int move_overhead_ms;    /* planning: command and poll latency per leg (default 35) */
        int move_timeout_ms;     /* 0 = derived from distance, speed and accel */
        /* motion semantics of the EPICS motor record, applied above every backend */
        double backlash_deg;   /* > 0: final approach upwards by this much, < 0 downwards */
        double deadband_deg;   /* a move ends within this of its target; 0: in-position only */
        int move_retries;      /* extra moves to get within the deadband before "missed" */
        bool absolute_encoder; /* the position means something without homing */
        int direction;         /* continuous axes: 0 the shortest way, +1 always up, -1 down */
};

enum rig_switch_kind { RIG_SWITCH_LAMP, RIG_SWITCH_LASER };

#define RIG_LASER_MAX_ON_S 120.0 /* the default limits of time on */
#define RIG_LAMP_MAX_ON_S  3600.0

struct rig_switch_conf {
        char name[RIG_NAME_MAX];
        enum rig_switch_kind kind;
        char bus[RIG_NAME_MAX]; /* from the backend map */
        struct rig_backend_conf backend;
        int warmup_ms;   /* settle time after switching on */
        double max_on_s; /* switched off after this long on, 0: no limit (docs/rig-file.md) */
        bool off_on_disconnect; /* switched off when the client that switched it on outside a
                                 * session disconnects (default: true for a laser) */
        /* lamps: position on the light arm */
        double elevation_deg, radius_mm, azimuth_deg; /* azimuth: offset from arm zero */
        double intensity;                             /* radiant intensity, sim units */
        /* laser: plane containing the turntable axis at this azimuth */
        double laser_azimuth_deg;
        double laser_origin[3];
        double laser_width_mm, laser_power;
        int laser_channel; /* 0 red, 1 green, 2 blue */
};

struct rig_camera_conf {
        char name[RIG_NAME_MAX];
        char bus[RIG_NAME_MAX]; /* from the backend map */
        struct rig_backend_conf backend;
        double elevation_deg, distance_mm, azimuth_deg; /* on the camera arm */
        double target[3];                               /* look-at point, mm */
        int width, height;
        double fx, fy, cx, cy;
        double dist[5]; /* k1 k2 p1 p2 k3, OpenCV convention */
        int exposure_us;
        double gain;
        int max_exposure_us;  /* the most `set` allows for exposure_us; 0: the driver's range */
        double max_gain;      /* the most `set` allows for gain; 0: the driver's range */
        int bits;             /* 8 or 16 */
        int readout_ms;       /* planning: time per frame beyond the exposure (default 30) */
        double frame_rate;    /* frames/s at most: exposures start >= 1/frame_rate apart
                               * (default 30) */
        double occlusion_deg; /* planning: angular radius of the camera and its mount seen
                               * from the turntable centre; a lamp within it and farther away
                               * is hidden (default 5) */
};

struct rig_config {
        char path[RIG_PATH_MAX];
        char name[64];
        struct rig_bus_conf buses[RIG_MAX_BUSES];
        size_t n_buses;
        struct rig_modbus_profile profiles[4];
        size_t n_profiles;
        struct rig_axis_conf axes[RIG_MAX_AXES];
        size_t n_axes;
        struct rig_switch_conf lamps[RIG_MAX_LAMPS];
        size_t n_lamps;
        /* the line lasers: the list `lasers`, or the one mapping `laser` (shorthand) */
        struct rig_switch_conf lasers[RIG_MAX_LASERS];
        size_t n_lasers;
        struct rig_camera_conf cameras[RIG_MAX_CAMERAS];
        size_t n_cameras;
        /* the calibration file (key `calibration`), an absolute path; "" when the rig file
         * names none. Not read by rigconf: it may not exist yet. */
        char calibration[RIG_PATH_MAX];
        const struct rig_backend *const *backends; /* the table given to rigconf_load() */
        char *text;                                /* the file's bytes, stored with every dataset */
        struct yconf yc;                           /* open document, for rigconf_scene() */
};

/* Loads and validates a rig file; backends is the NULL-terminated table of the backends a
 * device entry may name (registry_backends in drivers/registry.c), borrowed for the
 * config's lifetime. On error returns -errno and writes "FILE:LINE: key 'x': reason" into
 * err. *ret must be freed with rigconf_free(). */
int rigconf_load(const char *path, const struct rig_backend *const *backends,
                 struct rig_config **ret, char *err, size_t errlen);

/* rigconf_load() of the rig file stored with a dataset (its rig.yaml), read offline: a
 * ${VAR} that is unset here is kept as written, not an error (the ports it names are not
 * opened). */
int rigconf_load_stored(const char *path, const struct rig_backend *const *backends,
                        struct rig_config **ret, char *err, size_t errlen);

/* Frees a rig config; NULL is a no-op. Returns NULL. */
struct rig_config *rigconf_free(struct rig_config *rc);

/* The scene mapping node (gonio-sim only); NULL if absent. Valid until rigconf_free. */
struct fy_node *rigconf_scene(struct rig_config *rc);

/* The rig-file name of bus type t ("modbus-rtu", ...). */
const char *rigconf_bus_type_name(enum rig_bus_type t);

/* Lookups by name; NULL if absent. */
const struct rig_bus_conf *rigconf_bus(const struct rig_config *rc, const char *name);
const struct rig_modbus_profile *rigconf_profile(const struct rig_config *rc, const char *name);

/* Index of the laser named name in rc, or -ENOENT when the rig has none of that name. */
int rigconf_laser(const struct rig_config *rc, const char *name);

/* The bit set of all of rc's lasers (struct gn_pose.lasers). */
uint32_t rigconf_all_lasers(const struct rig_config *rc);

/* Index of the axis of role in rc, or -ENOENT when the rig has none. */
int rigconf_axis_of_role(const struct rig_config *rc, enum gn_role role);

/* Fills p with the built-in "gonio-default" register profile. */
void rigconf_default_profile(struct rig_modbus_profile *p);
