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
