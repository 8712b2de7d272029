/* discover.c - devices a rig file could name (see discover.h). Each family walks one sysfs
 * folder; V4L2 nodes and gpiochips are then asked, read-only, for their formats, controls and
 * lines through the kernel's uapi (plain ioctls: no device library), and libcamera lists its
 * cameras through the shim. Nothing is acquired or configured, so listing is safe while goniod
 * drives the rig. */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <libgen.h>
#include <limits.h>
#include <linux/gpio.h>
#include <linux/videodev2.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <unistd.h>

#include "common/cleanup.h"
#include "drivers/camera/libcamera/lc_shim.h"
#include "drivers/discover.h"

#define RELAY_VID "16c0"
#define RELAY_PID "05df"

/* Reads the first line of DIR/NAME into buf (newline dropped); "" when absent. */
static const char *read_attr(const char *dir, const char *name, char *buf, size_t len)
{
        char path[PATH_MAX];
        _cleanup_fclose_ FILE *f = NULL;

        buf[0] = 0;
        snprintf(path, sizeof(path), "%s/%s", dir, name);
        f = fopen(path, "re");
        if (f && fgets(buf, len, f))
                buf[strcspn(buf, "\n")] = 0;
        return buf;
}

/* The last component of the symlink DIR/NAME (a driver's name), or "". */
static const char *link_name(const char *dir, const char *name, char *buf, size_t len)
{
        char path[PATH_MAX], target[PATH_MAX];
        ssize_t n;

        snprintf(path, sizeof(path), "%s/%s", dir, name);
        n = readlink(path, target, sizeof(target) - 1);
        if (n <= 0)
                return buf[0] = 0, buf;
        target[n] = 0;
        snprintf(buf, len, "%s", basename(target));
        return buf;
}

/* The USB vid:pid of the device dir belongs to (its nearest ancestor with idVendor). */
static const char *usb_ancestor(const char *dir, char *buf, size_t len)
{
        char path[PATH_MAX], vid[8], pid[8];

        if (!realpath(dir, path))
                return buf[0] = 0, buf;
        for (char *slash; (slash = strrchr(path, '/')) && slash != path; *slash = 0)
                if (*read_attr(path, "idVendor", vid, sizeof(vid))) {
                        snprintf(buf, len, "%s:%s", vid, read_attr(path, "idProduct", pid, 8));
                        return buf;
                }
        return buf[0] = 0, buf;
}

/* Calls fn for each entry of SYSFS/sub whose name starts with prefix, in version order
 * (video2 before video10). */
static void each_entry(const char *sysfs, const char *sub, const char *prefix, json_t *out,
                       void (*fn)(const char *dir, const char *name, json_t *out))
{
        char path[PATH_MAX];
        struct dirent **de;
        int n;

        snprintf(path, sizeof(path), "%s/%s", sysfs, sub);
        if ((n = scandir(path, &de, NULL, versionsort)) < 0)
                return;
        for (int i = 0; i < n; i++) {
                char dir[PATH_MAX];
                const char *name = de[i]->d_name;
                if (name[0] != '.' && strncmp(name, prefix, strlen(prefix)) == 0) {
                        snprintf(dir, sizeof(dir), "%s/%s", path, name);
                        fn(dir, name, out);
                }
                free(de[i]);
        }
        free(de);
}

/* A tty with a device behind it (not a virtual console or pty). */
static void serial_one(const char *dir, const char *name, json_t *out)
{
        char dev[PATH_MAX], driver[64], usb[16];

        snprintf(dev, sizeof(dev), "%s/device", dir);
        if (access(dev, F_OK) < 0)
                return;
        json_array_append_new(out,
                              json_pack("{s:s+, s:s, s:s*}", "path", "/dev/", name, "driver",
                                        link_name(dev, "driver", driver, sizeof(driver)), "usb",
                                        *usb_ancestor(dev, usb, sizeof(usb)) ? usb : NULL));
}

/* Opens /dev/NAME read-only when it is the device of the sysfs folder dir (same major:minor as
 * its "dev" attribute): a fake sysfs tree (tests) never opens this machine's devices. Returns
 * the fd or -errno (-ENODEV when it is not that device). */
static int open_node(const char *dir, const char *name)
{
        char path[PATH_MAX], dev[32];
        unsigned maj, min;
        struct stat st;
        int fd;

        if (sscanf(read_attr(dir, "dev", dev, sizeof(dev)), "%u:%u", &maj, &min) != 2)
                return -ENODEV;
        snprintf(path, sizeof(path), "/dev/%s", name);
        if ((fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC)) < 0)
                return -errno;
        if (fstat(fd, &st) < 0 || !S_ISCHR(st.st_mode) || st.st_rdev != makedev(maj, min)) {
                close(fd);
                return -ENODEV;
        }
        return fd;
}

/* Sets "error" on o for a node that exists but cannot be asked (not a missing one). */
static void node_error(json_t *o, int err)
{
        if (err != -ENODEV && err != -ENOENT)
                json_object_set_new(o, "error", json_string(strerror(-err)));
}

/* A fourcc as its four characters, trailing blanks dropped ("YUYV", "GREY"); the big-endian
 * flag (bit 31, V4L2 and DRM alike) is dropped, anything else unprintable becomes '?'. */
static const char *fourcc_str(uint32_t f, char buf[5])
{
        f &= ~(1u << 31);
        for (int i = 0; i < 4; i++) {
                buf[i] = (char)((f >> (8 * i)) & 0xff);
                if (buf[i] < ' ' || buf[i] > '~')
                        buf[i] = '?';
        }
        buf[4] = 0;
        for (int i = 3; i > 0 && buf[i] == ' '; i--)
                buf[i] = 0;
        return buf;
}

/* Sets "sizes" ([{width, height}], discrete) or "range" (stepwise) on the format f. */
static void v4l2_sizes(int fd, uint32_t fourcc, json_t *f)
{
        struct v4l2_frmsizeenum fs = {.pixel_format = fourcc};
        json_t *sizes = json_array();

        for (; ioctl(fd, VIDIOC_ENUM_FRAMESIZES, &fs) == 0; fs.index++) {
                if (fs.type != V4L2_FRMSIZE_TYPE_DISCRETE) {
                        const struct v4l2_frmsize_stepwise *w = &fs.stepwise;
                        json_object_set_new(f, "range",
                                            json_pack("{s:i, s:i, s:i, s:i, s:i, s:i}", "min_width",
                                                      w->min_width, "max_width", w->max_width,
                                                      "step_width", w->step_width, "min_height",
                                                      w->min_height, "max_height", w->max_height,
                                                      "step_height", w->step_height));
                        break;
                }
                json_array_append_new(sizes, json_pack("{s:i, s:i}", "width", fs.discrete.width,
                                                       "height", fs.discrete.height));
        }
        json_object_set_new(f, "sizes", sizes);
}

/* The capture formats of the node: [{fourcc, description, sizes, range?}]. */
static json_t *v4l2_formats(int fd)
{
        struct v4l2_capability cap = {0};
        struct v4l2_fmtdesc desc = {0};
        json_t *list = json_array();
        char cc[5];

        if (ioctl(fd, VIDIOC_QUERYCAP, &cap) < 0)
                return list;
        if (cap.capabilities & V4L2_CAP_DEVICE_CAPS)
                cap.capabilities = cap.device_caps;
        if (cap.capabilities & V4L2_CAP_VIDEO_CAPTURE)
                desc.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
        else if (cap.capabilities & V4L2_CAP_VIDEO_CAPTURE_MPLANE)
                desc.type = V4L2_BUF_TYPE_VIDEO_CAPTURE_MPLANE;
        else
                return list;
        for (; ioctl(fd, VIDIOC_ENUM_FMT, &desc) == 0; desc.index++) {
                json_t *f = json_pack("{s:s, s:s}", "fourcc", fourcc_str(desc.pixelformat, cc),
                                      "description", (const char *)desc.description);
                v4l2_sizes(fd, desc.pixelformat, f);
                json_array_append_new(list, f);
        }
        return list;
}

/* A V4L2 control type as devices names it; "other" for compound and newer types. */
static const char *ctrl_type(uint32_t type)
{
        static const char *const names[] = {
                [V4L2_CTRL_TYPE_INTEGER] = "integer",
                [V4L2_CTRL_TYPE_BOOLEAN] = "boolean",
                [V4L2_CTRL_TYPE_MENU] = "menu",
                [V4L2_CTRL_TYPE_BUTTON] = "button",
                [V4L2_CTRL_TYPE_INTEGER64] = "integer64",
                [V4L2_CTRL_TYPE_STRING] = "string",
                [V4L2_CTRL_TYPE_BITMASK] = "bitmask",
                [V4L2_CTRL_TYPE_INTEGER_MENU] = "integer_menu",
        };

        return type < ELEMENTSOF(names) && names[type] ? names[type] : "other";
}

/* The node's controls, class controls and disabled ones left out:
 * [{name, type, min, max, step, default}]. */
static json_t *v4l2_controls(int fd)
{
        struct v4l2_query_ext_ctrl q = {.id = V4L2_CTRL_FLAG_NEXT_CTRL};
        json_t *list = json_array();

        for (; ioctl(fd, VIDIOC_QUERY_EXT_CTRL, &q) == 0; q.id |= V4L2_CTRL_FLAG_NEXT_CTRL) {
                if (q.type == V4L2_CTRL_TYPE_CTRL_CLASS || (q.flags & V4L2_CTRL_FLAG_DISABLED))
                        continue;
                json_array_append_new(
                        list, json_pack("{s:s, s:s, s:I, s:I, s:I, s:I}", "name", q.name, "type",
                                        ctrl_type(q.type), "min", (json_int_t)q.minimum, "max",
                                        (json_int_t)q.maximum, "step", (json_int_t)q.step,
                                        "default", (json_int_t)q.default_value));
        }
        return list;
}

/* A V4L2 node: its card name, then its formats and controls when its /dev node opens. */
static void v4l2_one(const char *dir, const char *name, json_t *out)
{
        char card[128];
        json_t *o = json_pack("{s:s+, s:s}", "path", "/dev/", name, "name",
                              read_attr(dir, "name", card, sizeof(card)));
        _cleanup_close_ int fd = open_node(dir, name);

        if (o && fd >= 0) {
                json_object_set_new(o, "formats", v4l2_formats(fd));
                json_object_set_new(o, "controls", v4l2_controls(fd));
        } else if (o)
                node_error(o, fd);
        json_array_append_new(out, o);
}

/* The chip's label and lines ([{offset, name, consumer, direction, used, active_low}]). */
static void gpio_lines(int fd, json_t *o)
{
        struct gpiochip_info chip = {0};
        json_t *lines = json_array();

        if (ioctl(fd, GPIO_GET_CHIPINFO_IOCTL, &chip) < 0) {
                node_error(o, -errno);
                json_decref(lines);
                return;
        }
        for (uint32_t i = 0; i < chip.lines; i++) {
                struct gpio_v2_line_info li = {.offset = i};
                if (ioctl(fd, GPIO_V2_GET_LINEINFO_IOCTL, &li) < 0)
                        break;
                json_array_append_new(
                        lines,
                        json_pack("{s:i, s:s, s:s, s:s, s:b, s:b}", "offset", i, "name", li.name,
                                  "consumer", li.consumer, "direction",
                                  li.flags & GPIO_V2_LINE_FLAG_OUTPUT ? "output" : "input", "used",
                                  !!(li.flags & GPIO_V2_LINE_FLAG_USED), "active_low",
                                  !!(li.flags & GPIO_V2_LINE_FLAG_ACTIVE_LOW)));
        }
        json_object_set_new(o, "label", json_string(chip.label));
        json_object_set_new(o, "lines", lines);
}

/* A gpiochip: its driver, then its label and lines when its /dev node opens. */
static void gpio_one(const char *dir, const char *name, json_t *out)
{
        char driver[64];
        json_t *o = json_pack("{s:s+, s:s}", "path", "/dev/", name, "driver",
                              link_name(dir, "../driver", driver, sizeof(driver)));
        _cleanup_close_ int fd = open_node(dir, name);

        if (o && fd >= 0)
                gpio_lines(fd, o);
        else if (o)
                node_error(o, fd);
        json_array_append_new(out, o);
}

/* A USB device (not an interface): vid:pid, strings, and the relay count of a HID relay
 * board ("USBRelayN" on 16c0:05df). */
static void usb_one(const char *dir, const char *name, json_t *out)
{
        char vid[8], pid[8], product[128], maker[128], serial[64];
        json_t *o;
        int relays = 0;

        if (!*read_attr(dir, "idVendor", vid, sizeof(vid)))
                return;
        read_attr(dir, "idProduct", pid, sizeof(pid));
        read_attr(dir, "product", product, sizeof(product));
        o = json_pack("{s:s, s:s++, s:s, s:s, s:s}", "bus_path", name, "id", vid, ":", pid,
                      "manufacturer", read_attr(dir, "manufacturer", maker, sizeof(maker)),
                      "product", product, "serial",
                      read_attr(dir, "serial", serial, sizeof(serial)));
        if (o && strcmp(vid, RELAY_VID) == 0 && strcmp(pid, RELAY_PID) == 0 &&
            sscanf(product, "USBRelay%d", &relays) == 1)
                json_object_set_new(o, "relays", json_integer(relays));
        json_array_append_new(out, o);
}

static const struct family {
        const char *key, *sub, *prefix;
        void (*fn)(const char *dir, const char *name, json_t *out);
} families[] = {
        {"serial", "class/tty", "tty", serial_one},
        {"v4l2", "class/video4linux", "video", v4l2_one},
        {"gpio", "bus/gpio/devices", "gpiochip", gpio_one},
        {"usb", "bus/usb/devices", "", usb_one},
};

/* One libcamera camera: {id, model, formats: [{fourcc, name, sizes, range}]}. */
static void lc_one(const struct lc_camera_info *info, void *data)
{
        json_t *formats = json_array();

        for (size_t i = 0; i < info->nformats; i++) {
                const struct lc_format_info *f = &info->formats[i];
                json_t *sizes = json_array();
                char cc[5];
                for (size_t k = 0; k < f->nsizes; k++)
                        json_array_append_new(sizes,
                                              json_pack("{s:i, s:i}", "width", f->sizes[k].width,
                                                        "height", f->sizes[k].height));
                json_array_append_new(formats,
                                      json_pack("{s:s, s:s, s:o, s:{s:i, s:i, s:i, s:i}}", "fourcc",
                                                fourcc_str(f->fourcc, cc), "name", f->name, "sizes",
                                                sizes, "range", "min_width", f->min.width,
                                                "min_height", f->min.height, "max_width",
                                                f->max.width, "max_height", f->max.height));
        }
        json_array_append_new(data, json_pack("{s:s, s:s, s:o}", "id", info->id, "model",
                                              info->model, "formats", formats));
}

/* Sets "libcamera" (the cameras) and, when libcamera cannot list them, "libcamera_error".
 * libcamera logs to stderr: only fatal messages, unless LIBCAMERA_LOG_LEVELS asks for more. */
static void discover_libcamera(json_t *all)
{
        json_t *list = json_array();
        char cause[256] = "";

        setenv("LIBCAMERA_LOG_LEVELS", "*:FATAL", 0);
        if (lc_list(lc_one, list, cause, sizeof(cause)) < 0)
                json_object_set_new(all, "libcamera_error", json_string(cause));
        json_object_set_new(all, "libcamera", list);
}

json_t *discover_all(const char *sysfs)
{
        json_t *all = json_object();

        for (size_t i = 0; all && i < ELEMENTSOF(families); i++) {
                json_t *list = json_array();
                each_entry(sysfs, families[i].sub, families[i].prefix, list, families[i].fn);
                json_object_set_new(all, families[i].key, list);
        }
        if (all)
                discover_libcamera(all);
        return all;
}
