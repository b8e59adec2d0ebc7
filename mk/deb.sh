#!/bin/bash
# make deb: build the Debian packages out of tree. The working tree's files
# (tracked and untracked, not ignored; or all but build/ outside git) are
# copied to OUT/src/it2n-VERSION, dpkg-buildpackage -us -uc -b runs there,
# and the .deb, .ddeb, .changes and .buildinfo files land in OUT (the log in
# OUT/build.log), with the source package (.dsc, .tar.xz; dpkg-source -b on
# the pristine copy) for lintian. Nothing is written into the working tree.
# usage: mk/deb.sh OUT   (from the repository root)
set -euo pipefail
out=$1
ver=$(dpkg-parsechangelog -l debian/changelog -S Version)
rm -rf "$out"
src=$out/src/it2n-$ver
mkdir -p "$src"
if git rev-parse --is-inside-work-tree >/dev/null 2>&1; then
  git ls-files -z --cached --others --exclude-standard |
    while IFS= read -r -d '' f; do [ -e "$f" ] && printf '%s\0' "$f"; done |
    tar -cf - --null -T - | tar -xf - -C "$src"
else
  tar -cf - --exclude=./build --exclude=./.git . | tar -xf - -C "$src"
fi
echo "deb: building it2n $ver in $src (log: $out/build.log)"
# The source package first, from the pristine copy (for lintian: it checks
# debian/ itself), then the binary packages.
if ! (cd "$out/src" && dpkg-source -b "it2n-$ver") >"$out/build.log" 2>&1 ||
   ! (cd "$src" && dpkg-buildpackage -us -uc -b -J"${JOBS:-2}") >>"$out/build.log" 2>&1; then
  tail -n 40 "$out/build.log" >&2
  echo "deb: dpkg-buildpackage failed (full log: $out/build.log)" >&2
  exit 1
fi
mv "$out"/src/*.deb "$out"/src/*.changes "$out"/src/*.buildinfo "$out"/src/*.dsc "$out"/src/*.tar.* "$out"/
mv "$out"/src/*.ddeb "$out"/ 2>/dev/null || true
for f in "$out"/*.deb; do echo "deb: $f ($(du -k "$f" | cut -f1) KiB)"; done
