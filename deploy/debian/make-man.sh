#!/usr/bin/env bash
# make-man.sh BIN_DIR PROGRAM VERSION OUT: PROGRAM's manual page, gzipped,
# made by help2man from its --help (the build runs it for the package,
# deploy/debian/package.cmake). The page's NAME line is the text after the
# colon of the help's first line; locus's page also has a section per
# subcommand with that subcommand's --help.
set -euo pipefail
[ $# -eq 4 ] || { echo "usage: $0 BIN_DIR PROGRAM VERSION OUT" >&2; exit 2; }
bin=$1 prog=$2 version=$3 out=$4
# Found on the PATH, so that the usage lines name the program, not its path.
export PATH="$bin:$PATH"
inc=$(mktemp)
trap 'rm -f "$inc" "$out.part" "$out.part.roff"' EXIT

# Text as it is, in roff: no fill, backslashes and leading dots escaped,
# characters beyond ASCII (the section signs) as groff's \[uXXXX] (help2man
# would turn them into question marks).
verbatim() {
  echo ".nf"
  sed -e 's/\\/\\e/g' -e "s/^[.']/\\\\\\&&/" |
    perl -CSD -pe 's/([^\x00-\x7f])/sprintf("\\[u%04X]", ord($1))/ge'
  echo ".fi"
}

help=$("$prog" --help)
name=$(printf '%s\n' "$help" | head -1 | sed 's/^[^:]*: *//')
if [ "$prog" = locus ]; then
  echo "[SUBCOMMANDS]" >>"$inc"
  subs=$(printf '%s\n' "$help" | sed -n '/^Subcommands:/,$p' | awk 'NR > 1 && /^  [a-z]/ {print $1}')
  [ -n "$subs" ] || { echo "make-man: no subcommands in locus --help" >&2; exit 1; }
  for sub in $subs; do
    echo ".SS \"locus $sub\"" >>"$inc"
    "$prog" "$sub" --help | verbatim >>"$inc"
  done
fi
{
  echo "[SEE ALSO]"
  first=1
  for page in locus locus-coordinator locus-worker; do
    [ "$page" = "$prog" ] && continue
    [ $first = 1 ] || echo ","
    printf '.BR %s (1)' "$page"
    first=0
  done
  echo
  echo ".PP"
  echo "The systemd units locus-coordinator.service and locus-worker@.service read their flags from"
  echo ".IR /etc/locus/coordinator.conf \" and \" /etc/locus/worker.conf ."
} >>"$inc"

help2man --no-info --no-discard-stderr --version-string="$version" --name="$name" \
  --include="$inc" "$prog" >"$out.part.roff"
gzip -9n <"$out.part.roff" >"$out.part"
mv "$out.part" "$out"
