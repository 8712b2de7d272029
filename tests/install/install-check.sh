#!/bin/bash
# install-check.sh - `meson install --destdir` of the build into a temporary tree, then the
# tree: the programs (which run and say their version), the man pages (`man -M` finds
# goniod(8) and the others), the bash completion (completes commands, groups and options),
# the systemd unit, sysusers and tmpfiles snippets where Debian keeps them, and the docs
# where the unit's Documentation= points.
# Usage: install-check.sh BUILD_DIR PREFIX MANDIR DATADIR VERSION
set -u
build=$1 prefix=$2 mandir=$3 datadir=$4 version=$5
dest=$(mktemp -d /tmp/gonio-install.XXXXXX)
trap 'rm -rf "$dest"' EXIT
fail() { echo "FAIL: $*"; exit 1; }

meson install -C "$build" --no-rebuild --destdir "$dest" --quiet >"$dest.log" 2>&1 ||
        { cat "$dest.log"; rm -f "$dest.log"; fail "meson install"; }
rm -f "$dest.log"
[[ $mandir = /* ]] || mandir=$prefix/$mandir
[[ $datadir = /* ]] || datadir=$prefix/$datadir
root=$dest$prefix

for prog in goniod gonioctl gonio-sim; do
        [ -x "$root/bin/$prog" ] || fail "bin/$prog missing"
        "$root/bin/$prog" --version | grep -q "^$prog $version" || fail "$prog --version"
done
for page in man1/gonioctl.1 man1/gonio-sim.1 man8/goniod.8 man5/gonio-rig.5 man5/gonio-session.5; do
        [ -f "$dest$mandir/$page" ] || fail "$mandir/$page missing"
done
if command -v man >/dev/null 2>&1; then
        for name in goniod gonioctl gonio-sim gonio-rig gonio-session; do
                MANWIDTH=80 man -M "$dest$mandir" "$name" 2>/dev/null | grep -q "^NAME" ||
                        fail "man -M $dest$mandir $name finds no page"
        done
fi
for f in lib/systemd/system/goniod.service lib/sysusers.d/gonio.conf lib/tmpfiles.d/gonio.conf; do
        [ -f "$root/$f" ] || fail "$f missing"
done
doc=$(sed -n 's|^Documentation=file:.*/doc/gonio/||p' "$root/lib/systemd/system/goniod.service")
[ -n "$doc" ] || fail "goniod.service has no Documentation= under doc/gonio"
[ -f "$dest$datadir/doc/gonio/$doc" ] || fail "doc/gonio/$doc (Documentation=) missing"
[ -f "$dest$datadir/doc/gonio/examples/rigs/sim.yaml" ] || fail "doc/gonio/examples missing"

completion=$dest$datadir/bash-completion/completions/gonioctl
[ -f "$completion" ] || fail "bash completion missing"
# the completion of the installed gonioctl: COMP_WORDS as bash would set them
complete_words() {
        PATH=$root/bin:$PATH bash -c 'source "$1"; shift; COMP_WORDS=("$@")
                COMP_CWORD=$((${#COMP_WORDS[@]} - 1)); _gonioctl; echo "${COMPREPLY[*]}"' \
                _ "$completion" "$@"
}
[[ " $(complete_words gonioctl da) " = *" dataset "* ]] || fail "completion of a command"
[[ " $(complete_words gonioctl dataset c) " = *" check close create "* ]] ||
        fail "completion of a group's command: $(complete_words gonioctl dataset c)"
[[ " $(complete_words gonioctl move --n) " = *" --no-wait "* ]] || fail "completion of an option"
[[ " $(complete_words gonioctl wait --state f) " = " fault " ]] || fail "completion of --state"
echo "ok: installed into $dest$prefix"
