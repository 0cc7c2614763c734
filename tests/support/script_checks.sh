# Shared by the script smoke tests (tests/*_smoke.sh that take SOURCE_DIR BUILD_DIR): sourced
# after `set -u`, it sets src, build and a temporary folder tmp (removed at exit), and gives
# ok / fail (counted) and finish NAME, which prints the count and exits non-zero on any failure.
src="$1"
build="$2"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
fails=0
ok() { echo "ok   $*"; }
fail() { echo "FAIL $*"; fails=$((fails + 1)); }
finish() {
  echo "$1: $fails failure(s)"
  [ "$fails" -eq 0 ]
  exit $?
}
