/* discover.h - what a rig file could name on this machine: serial ports, V4L2 nodes with
 * their formats and controls, gpiochips with their lines, USB devices (HID relay boards
 * marked) and libcamera cameras, so an operator can write a rig file before goniod runs
 * (`gonioctl devices`). Found in sysfs; V4L2 nodes and gpiochips are then opened read-only
 * and queried (nothing acquired, configured or requested), libcamera through its shim. The
 * sysfs families are a table (discover.c). */
#pragma once

#include <jansson.h>

/* Lists the devices below sysfs (normally "/sys") as {"serial": [...], "v4l2": [...],
 * "gpio": [...], "usb": [...], "libcamera": [...]}, with "libcamera_error" when libcamera
 * cannot list (docs/gonioctl.md, "devices"). A family whose folder is missing gives an empty
 * list; a /dev node that is not the sysfs entry's device (another tree) is listed unqueried.
 * New reference, or NULL without memory. */
json_t *discover_all(const char *sysfs);
