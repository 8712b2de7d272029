/* fuzz-gcode.c - libFuzzer target of the G-code reply parser (drivers/axis/gcode/proto.c):
 * the input is what a controller prints on the serial line, cut into lines at '\n' (a
 * trailing '\r' dropped, as the serial transport does), each classified by gc_parse_line. A
 * parsed line's text must lie within the line. */
#include <stdlib.h>
#include <string.h>

#include "drivers/axis/gcode/proto.h"
#include "fuzz.h"

static void parse_line(char *line, size_t len)
{
        struct gc_line l;

        if (len > 0 && line[len - 1] == '\r')
                line[--len] = '\0';
        if (gc_parse_line(line, &l) < 0)
                return;
        if (l.text && *l.text && (l.text < line || l.text + strlen(l.text) > line + len))
                abort();
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
        char *text = fuzz_cstr(data, size), *p = text, *end = text + size;

        while (p <= end) {
                char *nl = memchr(p, '\n', (size_t)(end - p));
                size_t len = nl ? (size_t)(nl - p) : (size_t)(end - p);

                p[len] = '\0';
                parse_line(p, strlen(p));
                p += len + 1;
        }
        free(text);
        return 0;
}
