# testlib.sh -- helpers shared by the shell test scripts under tests/.
#   . "$(dirname "$0")/../lib/testlib.sh"
#   tl_init NAME [TMP-PREFIX]     # T (temp dir), FAILS=0, exit trap
#   tl_on_exit() { kill ...; }    # optional: run first by the exit trap
#   TL_KEEP=1                     # keep $T even when every check passed
#   ok WHAT / fail WHAT / skip REASON / skip_suite REASON / say TEXT
#   TL_FAIL_FAST=1                # fail exits 1 at once (scripts that stop at the first)
#   PORT=$(free_port)             # below the ephemeral range, unique per run
#   wait_port PORT [PID] [TRIES]  # until 127.0.0.1:PORT accepts (0.05 s apart)
#   tl_wait_served PID            # until $PLC reads from it2nd on $PORT (0), or PID died (1)
#   tl_stop PID [SIGNAL]          # kill -SIGNAL (TERM), wait: its exit status
#   tl_finish [LOG [LINES]]       # exit 1 (logs kept, LOG's tail shown) if a check failed or none ran
# Output follows `make test`'s runner (tests/run_suites.py): "NAME: ok: ...",
# "NAME: FAIL: ..." on stderr, "NAME: skip: reason", "skip suite: reason".
TL_LIB=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
TL_PY=/usr/bin/python3
FAILS=0
TL_CHECKS=0
TL_SKIPS=0

tl_init() { # name [temp-dir prefix]
    TL_NAME=$1
    T=$(mktemp -d "${TMPDIR:-/tmp}/${2:-it2n-$1}.XXXXXX")
    trap 'tl_cleanup' EXIT
}
tl_cleanup() {
    if declare -F tl_on_exit >/dev/null; then tl_on_exit; fi
    if [ "$FAILS" = 0 ] && [ -z "${TL_KEEP:-}" ]; then rm -rf "$T"; else echo "$TL_NAME: logs kept in $T" >&2; fi
}
ok() { echo "$TL_NAME: ok: $*"; TL_CHECKS=$((TL_CHECKS + 1)); }
fail() { # with TL_FAIL_FAST set, the first failure ends the script (exit 1)
    echo "$TL_NAME: FAIL: $*" >&2
    FAILS=$((FAILS + 1))
    TL_CHECKS=$((TL_CHECKS + 1))
    if [ -n "${TL_FAIL_FAST:-}" ]; then exit 1; fi
    return 0
}
say() { echo "$TL_NAME: $*"; }
skip() { echo "$TL_NAME: skip: $*"; TL_SKIPS=$((TL_SKIPS + 1)); }
skip_suite() { echo "skip suite: $*"; exit 0; }
free_port() { # the ports given so far are kept in $T/.ports: $(free_port) is a subshell
    local p
    # shellcheck disable=SC2046
    p=$(PYTHONPATH=$TL_LIB $TL_PY -m it2ntest.ports $(cat "$T/.ports" 2>/dev/null)) || return 1
    echo "$p" >> "$T/.ports"
    echo "$p"
}
wait_port() { # port [pid] [tries]: 0 once it accepts, 1 if pid exits or after tries
    local i
    for ((i = 0; i < ${3:-100}; i++)); do
        (exec 3<>"/dev/tcp/127.0.0.1/$1") 2>/dev/null && return 0
        [ -n "${2:-}" ] && ! kill -0 "$2" 2>/dev/null && return 1
        sleep 0.05
    done
    return 1
}
# it2nd helpers (need $PLC, the simulated PLC, and $PORT, its Modbus TCP port)
tl_wait_served() { # pid: 0 once $PLC reads register 0 on 127.0.0.1:$PORT; 1 if pid exits first or after ~5 s
    local i
    for ((i = 0; i < 100; i++)); do
        "$PLC" --tcp "127.0.0.1:$PORT" read 0 1 >/dev/null 2>&1 && return 0
        kill -0 "$1" 2>/dev/null || return 1
        sleep 0.05
    done
    return 1
}
tl_stop() { # pid [signal, default TERM]: signal it, wait; its exit status
    kill -"${2:-TERM}" "$1"
    wait "$1" 2>/dev/null
}
tl_finish() { # [LOG [LINES]]: exit 1 if any check failed (then LOG's last LINES, 40, on stderr) or none
    # ran and nothing was skipped (a script that asserted nothing has not passed); else 0
    if [ "$TL_CHECKS" = 0 ] && [ "$TL_SKIPS" = 0 ]; then fail "no check ran"; fi
    if [ "$FAILS" != 0 ]; then
        if [ -n "${1:-}" ]; then tail -n "${2:-40}" "$1" >&2; fi
        echo "$TL_NAME: $FAILS of $TL_CHECKS check(s) FAILED" >&2
        exit 1
    fi
    echo "$TL_NAME: all $TL_CHECKS check(s) passed$([ "$TL_SKIPS" = 0 ] || echo "; $TL_SKIPS part(s) skipped")"
    exit 0
}
