# goniod.bash - bash completion of goniod, installed as share/bash-completion/completions/goniod.
# Its options come from `goniod --help`, so they never drift from the program.
_goniod()
{
        local cur=${COMP_WORDS[COMP_CWORD]} prev=${COMP_WORDS[COMP_CWORD - 1]}

        COMPREPLY=()
        case $prev in
        --rig | --socket | --admin-socket | --token-file)
                COMPREPLY=($(compgen -f -- "$cur")); return ;;
        --data) COMPREPLY=($(compgen -d -- "$cur")); return ;;
        --listen-tcp | --listen-http)
                COMPREPLY=($(compgen -W "127.0.0.1: [::1]:" -- "$cur")); compopt -o nospace; return ;;
        --preview-fps) COMPREPLY=($(compgen -W "1 2 4 10" -- "$cur")); return ;;
        esac
        COMPREPLY=($(compgen -W "$(goniod --help 2>/dev/null | grep -o -- '--[a-z][a-z-]*' | sort -u)" -- "$cur"))
}
complete -F _goniod goniod
