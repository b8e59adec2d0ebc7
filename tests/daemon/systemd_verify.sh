#!/bin/bash
# systemd-analyze verify on the units, with ExecStart pointing at the
# freshly built binary (verify checks that the executable exists).
set -eu
BIN=$(cd "$(dirname "$1")" && pwd)/$(basename "$1")
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
T=$(mktemp -d /tmp/it2nd-units.XXXXXX)
trap 'rm -rf "$T"' EXIT
for u in it2nd.service it2nd@.service; do
    sed "s|/usr/local/sbin/it2nd|$BIN|" "$ROOT/daemon/$u" > "$T/$u"
done
mv "$T/it2nd@.service" "$T/it2nd@ttyUSB0.service"
# Any output (warnings included) or a non-zero status fails.
if ! out=$(cd "$T" && systemd-analyze verify --man=no it2nd.service it2nd@ttyUSB0.service 2>&1) || [ -n "$out" ]; then
    echo "$out"; echo "systemd-analyze verify: FAIL"; exit 1
fi
echo "systemd-analyze verify: units clean"

# The template is as hardened as the main unit: every [Service] setting of
# it2nd.service but the instance-specific ones is in it2nd@.service too.
service() { sed -n '/^\[Service\]/,/^\[/p' "$1" | grep -E '^[A-Za-z]+=' | grep -vE '^(ExecStart|StateDirectory|WorkingDirectory)='; }
missing=$(comm -23 <(service "$ROOT/daemon/it2nd.service" | sort) <(service "$ROOT/daemon/it2nd@.service" | sort))
if [ -n "$missing" ]; then
    echo "it2nd@.service lacks settings of it2nd.service:"; echo "$missing"; exit 1
fi
echo "it2nd@.service has every hardening setting of it2nd.service"

# Exposure (systemd-analyze security, offline): at most 2.5 for both.
if ! systemd-analyze security --help 2>/dev/null | grep -q -- '--offline'; then
    echo "systemd-analyze security --offline not available (systemd < 250): exposure not measured"
    exit 0
fi
for u in it2nd.service it2nd@ttyUSB0.service; do
    line=$(cd "$T" && systemd-analyze security --offline=yes --no-pager "$u" 2>&1 | grep 'Overall exposure level')
    level=$(echo "$line" | sed -n 's/.*: \([0-9.]*\) .*/\1/p')
    if [ -z "$level" ] || ! awk -v l="$level" 'BEGIN { exit !(l <= 2.5) }'; then
        echo "systemd-analyze security $u: '${line:-no result}' (want <= 2.5)"; exit 1
    fi
    echo "systemd-analyze security $u: exposure $level (<= 2.5)"
done
