/* rigconf.h - the rig file: every device of a capture rig, its backend and
 * connection, its geometry and its limits (see docs/rig-file.md).
 *
 * Loaded once by goniod and by gonio-sim from the same YAML file. The parsed
 * struct is plain data; the YAML document stays open so that gonio-sim can read
 * the scene section through rigconf_scene(). */
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

struct rig_axis_conf {
        char name[RIG_NAME_MAX];
        char backend[RIG_NAME_MAX]; /* "modbus" */
        char bus[RIG_NAME_MAX];
        int unit;                   /* Modbus unit id */
        char profile[RIG_NAME_MAX]; /* name of a profile; "gonio-default" is built in */
        int role;                   /* enum gn_role, or -1: moves nothing the pose records */
        bool continuous;            /* wraps at 360 deg; no soft limits */
        double min_deg, max_deg;    /* soft limits (when !continuous) */
        double max_speed;           /* deg/s */
        double accel;               /* deg/s^2 */
        int settle_ms;              /* extra wait after in-position */
        int move_timeout_ms;        /* 0 = derived from distance, speed and accel */
};

enum rig_switch_kind { RIG_SWITCH_LAMP, RIG_SWITCH_LASER };

struct rig_switch_conf {
        char name[RIG_NAME_MAX];
        enum rig_switch_kind kind;
        char backend[RIG_NAME_MAX]; /* "modbus-coil" */
        char bus[RIG_NAME_MAX];
        int unit;
        int coil;
        int warmup_ms; /* settle time after switching on */
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
        char backend[RIG_NAME_MAX]; /* "sim" */
        char bus[RIG_NAME_MAX];
        double elevation_deg, distance_mm, azimuth_deg; /* on the camera arm */
        double target[3];                               /* look-at point, mm */
        int width, height;
        double fx, fy, cx, cy;
        double dist[5]; /* k1 k2 p1 p2 k3, OpenCV convention */
        int exposure_us;
        double gain;
        int bits; /* 8 or 16 */
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
        struct rig_switch_conf laser;
        bool has_laser;
        struct rig_camera_conf cameras[RIG_MAX_CAMERAS];
        size_t n_cameras;
        char *text;      /* the file's bytes, stored with every dataset */
        struct yconf yc; /* open document, for rigconf_scene() */
};

/* Loads and validates a rig file. On error returns -errno and writes
 * "FILE:LINE: key 'x': reason" into err. *ret must be freed with rigconf_free(). */
int rigconf_load(const char *path, struct rig_config **ret, char *err, size_t errlen);

/* Frees a rig config; NULL is a no-op. Returns NULL. */
struct rig_config *rigconf_free(struct rig_config *rc);

/* The scene mapping node (gonio-sim only); NULL if absent. Valid until rigconf_free. */
struct fy_node *rigconf_scene(struct rig_config *rc);

/* Lookups by name; NULL if absent. */
const struct rig_bus_conf *rigconf_bus(const struct rig_config *rc, const char *name);
const struct rig_modbus_profile *rigconf_profile(const struct rig_config *rc, const char *name);

/* Index of the axis of role in rc, or -ENOENT when the rig has none. */
int rigconf_axis_of_role(const struct rig_config *rc, enum gn_role role);

/* Fills p with the built-in "gonio-default" register profile. */
void rigconf_default_profile(struct rig_modbus_profile *p);
