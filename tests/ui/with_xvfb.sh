#!/usr/bin/env bash
# with_xvfb.sh COMMAND [ARGS...]: runs COMMAND with DISPLAY set to an X server of its own (Xvfb,
# local connections only; screen VH_XVFB_SCREEN, default 1280x1024x24), stopped when COMMAND
# ends; exits with COMMAND's status. Xvfb chooses a free display number itself (-displayfd) and
# says which once it accepts connections, so that tests started in parallel (ctest -j) never race
# for one (as `xvfb-run -a`, which picks the number before starting the server, can).
set -u
# Listing a GoogleTest program's cases (ctest's discovery at build time) needs no display.
for arg in "$@"; do
  [[ $arg == --gtest_list_tests ]] && exec "$@"
done
dir="$(mktemp -d -t vh-xvfb.XXXXXX)" || exit 1
pid=""
cleanup() {
  if [[ -n $pid ]]; then
    kill "$pid" 2>/dev/null
    wait "$pid" 2>/dev/null
  fi
  rm -rf "$dir"
}
trap cleanup EXIT
trap 'exit 143' TERM INT
Xvfb -displayfd 3 -screen 0 "${VH_XVFB_SCREEN:-1280x1024x24}" -nolisten tcp 3>"$dir/display" >"$dir/log" 2>&1 &
pid=$!
for _ in $(seq 1 600); do  # up to 30 s
  [[ $(cat "$dir/display" 2>/dev/null) == *[0-9]* ]] && break
  if ! kill -0 "$pid" 2>/dev/null; then
    echo "with_xvfb.sh: Xvfb did not start:" >&2
    cat "$dir/log" >&2
    exit 1
  fi
  sleep 0.05
done
display="$(tr -dc '0-9' <"$dir/display")"
if [[ -z $display ]]; then
  echo "with_xvfb.sh: Xvfb named no display within 30 s" >&2
  exit 1
fi
DISPLAY=":$display" "$@"
