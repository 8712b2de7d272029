/* discover.c - devices a rig file could name, read from sysfs (see discover.h). Each
 * family walks one sysfs folder; none opens a device, so listing is safe while goniod
 * drives the rig. */
#include <dirent.h>
#include <errno.h>
#include <libgen.h>
#include <limits.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "common/cleanup.h"
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

/* Calls fn for each entry of SYSFS/sub whose name starts with prefix. */
static void each_entry(const char *sysfs, const char *sub, const char *prefix, json_t *out,
                       void (*fn)(const char *dir, const char *name, json_t *out))
{
        char path[PATH_MAX];
        DIR *d;
        struct dirent *de;

        snprintf(path, sizeof(path), "%s/%s", sysfs, sub);
        if (!(d = opendir(path)))
                return;
        while ((de = readdir(d))) {
                char dir[PATH_MAX];
                if (de->d_name[0] == '.' || strncmp(de->d_name, prefix, strlen(prefix)) != 0)
                        continue;
                snprintf(dir, sizeof(dir), "%s/%s", path, de->d_name);
                fn(dir, de->d_name, out);
        }
        closedir(d);
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

static void v4l2_one(const char *dir, const char *name, json_t *out)
{
        char card[128];

        json_array_append_new(out, json_pack("{s:s+, s:s}", "path", "/dev/", name, "name",
                                             read_attr(dir, "name", card, sizeof(card))));
}

static void gpio_one(const char *dir, const char *name, json_t *out)
{
        char driver[64];

        json_array_append_new(out, json_pack("{s:s+, s:s}", "path", "/dev/", name, "driver",
                                             link_name(dir, "../driver", driver, sizeof(driver))));
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

json_t *discover_all(const char *sysfs)
{
        json_t *all = json_object();

        for (size_t i = 0; all && i < ELEMENTSOF(families); i++) {
                json_t *list = json_array();
                each_entry(sysfs, families[i].sub, families[i].prefix, list, families[i].fn);
                json_object_set_new(all, families[i].key, list);
        }
        return all;
}
