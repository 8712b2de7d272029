# gonioctl.bash - bash completion of gonioctl, installed as
# share/bash-completion/completions/gonioctl. Commands and options come from gonioctl itself
# (`gonioctl --help`, `gonioctl COMMAND --help`), so they never drift from the program; device
# names (axes, lamps, lasers, cameras) from `gonioctl describe` and DEVICE.SETTING from
# `gonioctl get` when goniod answers within 1 s.

# The device names of class $2 (axis, lamp, laser, camera; empty: every class), asked of
# goniod on the socket $1 (empty: the default one).
_gonioctl_devices()
{
        gonioctl ${1:+--socket "$1"} --timeout 1 describe 2>/dev/null |
                awk -v cls="$2" 'NR > 1 && /^[^ ]/ && (cls == "" || $2 == cls) { print $1 }'
}

# DEVICE.SETTING of every device setting (gonioctl get), asked of goniod on the socket $1.
_gonioctl_settings()
{
        gonioctl ${1:+--socket "$1"} --timeout 1 get 2>/dev/null | awk 'NR > 1 { print $1 "." $2 }'
}

# The commands (first words) of the usage, or the subcommands of the group $1.
_gonioctl_commands()
{
        gonioctl --help 2>/dev/null | awk -v g="$1" '
                /^Commands:/ { on = 1; next }
                /^$/ { on = 0 }
                on && /^  [a-z]/ { if (g == "") print $1; else if ($1 == g) print $2 }' | sort -u
}

# The options of the command words $@ (global ones too), from its --help.
_gonioctl_options()
{
        gonioctl "$@" --help 2>/dev/null | grep -o -- '--[a-z][a-z-]*' | sort -u
}

_gonioctl()
{
        local cur=${COMP_WORDS[COMP_CWORD]} prev=${COMP_WORDS[COMP_CWORD - 1]}
        local socket="" cmd=() i w

        for ((i = 1; i < COMP_CWORD; i++)); do
                w=${COMP_WORDS[i]}
                case $w in
                --socket) socket=${COMP_WORDS[i + 1]}; ((i++)) ;;
                --timeout | --camera | --exposure | --gain | --bits | --count | --from | \
                        --board | --laser | --calibration | --start | --end | --step | \
                        --mode | --lamps | --sphere | --lamp-radius | --rig | --state | \
                        --triangles | --format | --for | -o) ((i++)) ;;
                -*) ;;
                *) cmd+=("$w") ;;
                esac
        done
        case $prev in
        --socket | --rig | --from | --calibration | --board | -o)
                COMPREPLY=($(compgen -f -- "$cur")); return ;;
        --state)
                COMPREPLY=($(compgen -W "idle homing moving stopping capturing storing fault" -- "$cur")); return ;;
        --mode) COMPREPLY=($(compgen -W "continuous stop" -- "$cur")); return ;;
        --bits) COMPREPLY=($(compgen -W "8 16" -- "$cur")); return ;;
        --format) COMPREPLY=($(compgen -W "colmap nerfstudio ply rti gltf" -- "$cur")); return ;;
        --camera) COMPREPLY=($(compgen -W "$(_gonioctl_devices "$socket" camera)" -- "$cur")); return ;;
        --laser) COMPREPLY=($(compgen -W "$(_gonioctl_devices "$socket" laser)" -- "$cur")); return ;;
        --lamps) COMPREPLY=($(compgen -W "$(_gonioctl_devices "$socket" lamp)" -- "$cur")); return ;;
        --timeout | --exposure | --gain | --count | --start | --end | --step | --sphere | \
                --lamp-radius | --triangles | --for) return ;;
        esac
        if [[ $cur == -* ]]; then
                COMPREPLY=($(compgen -W "$(_gonioctl_options "${cmd[@]:0:2}")" -- "$cur"))
                return
        fi
        if ((${#cmd[@]} == 0)); then
                COMPREPLY=($(compgen -W "$(_gonioctl_commands)" -- "$cur"))
                return
        fi
        case ${cmd[0]}:${#cmd[@]} in
        dataset:1 | session:1 | fault:1 | calibrate:1 | model:1)
                COMPREPLY=($(compgen -W "$(_gonioctl_commands "${cmd[0]}")" -- "$cur")) ;;
        home:* | move:1)
                COMPREPLY=($(compgen -W "$(_gonioctl_devices "$socket" axis)" -- "$cur")) ;;
        lamp:1)
                COMPREPLY=($(compgen -W "$(_gonioctl_devices "$socket" lamp)" -- "$cur")) ;;
        laser:1 | lamp:2)
                COMPREPLY=($(compgen -W "on off" -- "$cur")) ;;
        laser:2)
                COMPREPLY=($(compgen -W "$(_gonioctl_devices "$socket" laser)" -- "$cur")) ;;
        get:1 | set:1)
                COMPREPLY=($(compgen -W "$(_gonioctl_settings "$socket")" -- "$cur")) ;;
        validate:1 | session:2 | scan:1)
                COMPREPLY=($(compgen -f -- "$cur")) ;;
        esac
}
complete -F _gonioctl gonioctl
