#!/usr/bin/env bash
# Fetches the public test corpora into .testdata/ (git-ignored): the pydicom and pydicom-data
# wheels (DICOM files in many transfer syntaxes) and the nibabel wheel (NIfTI-1/2 images).
# A wheel is a zip archive; it is unpacked, never installed.
set -euo pipefail
cd "$(dirname "$0")/.."
want="pydicom==3.0.2 pydicom-data==1.0.0 nibabel==5.4.2"
marker=.testdata/.complete
if [ -f "$marker" ] && [ "$(cat "$marker")" = "$want" ]; then exit 0; fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
python3 -m pip download --quiet --no-deps --dest "$tmp" $want
rm -rf .testdata && mkdir -p .testdata
for w in "$tmp"/*.whl; do python3 -m zipfile -e "$w" .testdata/; done
echo "$want" > "$marker"
echo "test corpora in .testdata/" >&2
