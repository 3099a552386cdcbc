# Sourced by the tests of the scripts' command lines. expect_usage_error
# WANTED-TEXT ARGS... runs "$script" ARGS and fails (fail MESSAGE, the
# caller's) unless it exits 2 with WANTED-TEXT on stderr; $work is the
# caller's scratch folder.
expect_usage_error() {
  local want=$1 status=0
  shift
  "$script" "$@" >"$work/out" 2>"$work/err" || status=$?
  [ "$status" -eq 2 ] || fail "'$*' exited $status, not 2: $(cat "$work/err")"
  grep -q -- "$want" "$work/err" || fail "'$*' did not say '$want': $(cat "$work/err")"
}
