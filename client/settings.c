/* settings.c - gonioctl get/set: device settings printed as one table, whatever the shape
 * of device.get's result (docs/protocol.md). */
#include <stdio.h>

#include "client/settings.h"

static void header(void)
{
        printf("%-14s %-12s %10s %10s %10s %-8s %s\n", "DEVICE", "SETTING", "VALUE", "MIN", "MAX",
               "UNIT", "LIMIT");
}

/* One row: setting s (an object with value, min, max, unit, limit) of device. */
static void row(const char *device, const char *setting, json_t *s)
{
        json_t *max = json_object_get(s, "max");

        if (!json_is_number(max)) {
                printf("%-14s %-12s %10g %10s %10s %-8s %s\n", device, setting,
                       json_number_value(json_object_get(s, "value")), "-", "-", "-",
                       "not settable");
                return;
        }
        printf("%-14s %-12s %10g %10g %10g %-8s %s\n", device, setting,
               json_number_value(json_object_get(s, "value")),
               json_number_value(json_object_get(s, "min")), json_number_value(max),
               json_string_value(json_object_get(s, "unit")) ?: "",
               json_string_value(json_object_get(s, "limit")) ?: "");
}

/* The rows of one device's {device, settings}. */
static void device_rows(json_t *d)
{
        const char *name = json_string_value(json_object_get(d, "device")) ?: "?", *key;
        json_t *s;

        json_object_foreach(json_object_get(d, "settings"), key, s) row(name, key, s);
}

void settings_print_get(json_t *r)
{
        json_t *devs = json_object_get(r, "devices"), *d;
        size_t i;

        header();
        if (json_object_get(r, "setting"))
                return row(json_string_value(json_object_get(r, "device")) ?: "?",
                           json_string_value(json_object_get(r, "setting")) ?: "?", r);
        if (!devs)
                return device_rows(r);
        json_array_foreach(devs, i, d) device_rows(d);
}

void settings_print_set(json_t *r)
{
        printf("%s.%s = %g\n", json_string_value(json_object_get(r, "device")) ?: "?",
               json_string_value(json_object_get(r, "setting")) ?: "?",
               json_number_value(json_object_get(r, "value")));
}
