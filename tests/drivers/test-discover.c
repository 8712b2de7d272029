/* test-discover.c - device discovery (drivers/discover.c) on a sysfs tree built the way
 * the kernel lays it out (class links into a devices hierarchy, attribute files), in a
 * temp dir: a USB serial adapter, a virtual console that is no port, a V4L2 node, a
 * gpiochip and a USB HID relay board. The V4L2 node's "dev" names another device than
 * /dev/video0 and the gpiochip has none: neither /dev node is asked (no formats, controls or
 * lines) and neither is an error. libcamera is always an array; the real sysfs of this
 * machine must not crash it. */
#include <errno.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <unistd.h>

#include "common/cleanup.h"
#include "drivers/discover.h"
#include "tests/test.h"

static char root[64];

static void mkdirs(const char *rel)
{
        char path[512], *p;

        snprintf(path, sizeof(path), "%s/%s", root, rel);
        for (p = path + strlen(root) + 1; (p = strchr(p, '/')); *p++ = '/') {
                *p = 0;
                CHECK(mkdir(path, 0755) == 0 || errno == EEXIST);
        }
        CHECK(mkdir(path, 0755) == 0 || errno == EEXIST);
}

static void attr(const char *rel, const char *value)
{
        char path[512];
        FILE *f;

        snprintf(path, sizeof(path), "%s/%s", root, rel);
        CHECK((f = fopen(path, "we")));
        fprintf(f, "%s\n", value);
        CHECK(fclose(f) == 0);
}

static void link_to(const char *target, const char *rel)
{
        char path[512];

        snprintf(path, sizeof(path), "%s/%s", root, rel);
        CHECK(symlink(target, path) == 0);
}

static void build_tree(void)
{
        mkdirs("devices/pci0/usb1/1-1/1-1:1.0/ttyUSB0/tty/ttyUSB0");
        attr("devices/pci0/usb1/1-1/idVendor", "0403");
        attr("devices/pci0/usb1/1-1/idProduct", "6001");
        mkdirs("bus/usb-serial/drivers/ftdi_sio");
        mkdirs("class/tty");
        link_to("../../devices/pci0/usb1/1-1/1-1:1.0/ttyUSB0/tty/ttyUSB0", "class/tty/ttyUSB0");
        link_to("../..", "devices/pci0/usb1/1-1/1-1:1.0/ttyUSB0/tty/ttyUSB0/device");
        link_to("../../../../../../bus/usb-serial/drivers/ftdi_sio",
                "devices/pci0/usb1/1-1/1-1:1.0/ttyUSB0/driver");
        mkdirs("devices/virtual/tty/tty1");
        link_to("../../devices/virtual/tty/tty1", "class/tty/tty1");
        mkdirs("devices/platform/vivid.0/video4linux/video0");
        attr("devices/platform/vivid.0/video4linux/video0/name", "vivid-000-vid-cap");
        attr("devices/platform/vivid.0/video4linux/video0/dev", "4095:4095");
        mkdirs("class/video4linux");
        link_to("../../devices/platform/vivid.0/video4linux/video0", "class/video4linux/video0");
        mkdirs("devices/platform/gpio-sim.0/gpiochip0");
        mkdirs("bus/platform/drivers/gpio-sim");
        link_to("../../bus/platform/drivers/gpio-sim", "devices/platform/gpio-sim.0/driver");
        mkdirs("bus/gpio/devices");
        link_to("../../../devices/platform/gpio-sim.0/gpiochip0", "bus/gpio/devices/gpiochip0");
        mkdirs("devices/pci0/usb1/1-2");
        attr("devices/pci0/usb1/1-2/idVendor", "16c0");
        attr("devices/pci0/usb1/1-2/idProduct", "05df");
        attr("devices/pci0/usb1/1-2/product", "USBRelay2");
        attr("devices/pci0/usb1/1-2/manufacturer", "www.dcttech.com");
        mkdirs("bus/usb/devices");
        link_to("../../../devices/pci0/usb1/1-1", "bus/usb/devices/1-1");
        link_to("../../../devices/pci0/usb1/1-2", "bus/usb/devices/1-2");
}

static json_t *only(json_t *all, const char *family)
{
        json_t *list = json_object_get(all, family);

        CHECK(json_is_array(list));
        CHECK_INT(json_array_size(list), 1);
        return json_array_get(list, 0);
}

static const char *field(json_t *o, const char *key)
{
        return json_string_value(json_object_get(o, key));
}

int main(void)
{
        static const char *const probed[] = {"formats", "controls", "lines", "label", "error"};
        json_t *all, *o, *usb;
        char cmd[128];

        snprintf(root, sizeof(root), "/tmp/gonio-sysfs-XXXXXX");
        CHECK(mkdtemp(root));
        build_tree();
        all = discover_all(root);
        CHECK(all);
        o = only(all, "serial"); /* tty1 has no device: not a port */
        CHECK_STR(field(o, "path"), "/dev/ttyUSB0");
        CHECK_STR(field(o, "driver"), "ftdi_sio");
        CHECK_STR(field(o, "usb"), "0403:6001");
        CHECK_STR(field(only(all, "v4l2"), "name"), "vivid-000-vid-cap");
        CHECK_STR(field(only(all, "v4l2"), "path"), "/dev/video0");
        CHECK_STR(field(only(all, "gpio"), "path"), "/dev/gpiochip0");
        CHECK_STR(field(only(all, "gpio"), "driver"), "gpio-sim");
        for (size_t i = 0; i < ELEMENTSOF(probed); i++) {
                CHECK(!json_object_get(only(all, "v4l2"), probed[i]));
                CHECK(!json_object_get(only(all, "gpio"), probed[i]));
        }
        CHECK(json_is_array(json_object_get(all, "libcamera")));
        usb = json_object_get(all, "usb");
        CHECK_INT(json_array_size(usb), 2);
        for (size_t i = 0; i < 2; i++) {
                o = json_array_get(usb, i);
                if (strcmp(field(o, "id"), "16c0:05df") == 0)
                        CHECK_INT(json_integer_value(json_object_get(o, "relays")), 2);
                else
                        CHECK(!json_object_get(o, "relays"));
        }
        json_decref(all);
        json_decref(discover_all("/sys")); /* this machine's own: must not crash */
        snprintf(cmd, sizeof(cmd), "rm -rf '%s'", root);
        CHECK(system(cmd) == 0);
        return 0;
}
