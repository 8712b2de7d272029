#!/bin/sh
# man-check.sh - renders each man page given at 80 columns with man(1) and fails on any
# warning of man or troff, on an empty page and on a page without NAME and SYNOPSIS.
# Usage: man-check.sh PAGE...  (exit 77 when man is not installed)
command -v man >/dev/null 2>&1 || { echo "man not installed"; exit 77; }
status=0
for page in "$@"; do
        warnings=$(MANWIDTH=80 man --warnings -l "$page" 2>&1 >/dev/null)
        if [ -n "$warnings" ]; then
                printf '%s: warnings:\n%s\n' "$page" "$warnings"
                status=1
        fi
        text=$(MANWIDTH=80 man -l "$page" 2>/dev/null)
        for section in NAME SYNOPSIS; do
                if ! printf '%s\n' "$text" | grep -q "^$section\$"; then
                        echo "$page: no $section section"
                        status=1
                fi
        done
done
exit $status
