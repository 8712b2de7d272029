/* settings.h - gonioctl get/set: the human output of device.get and device.set. */
#pragma once

#include <jansson.h>

/* Prints device.get's result, whichever of its three forms (every device, one device, one
 * setting), as a table: device, setting, value, range, unit, what sets the max. */
void settings_print_get(json_t *r);

/* Prints device.set's result: "turntable.speed = 45". */
void settings_print_set(json_t *r);
