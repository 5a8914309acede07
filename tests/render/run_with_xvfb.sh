#!/bin/sh
# Runs a command with DISPLAY set to a private Xvfb server. The server picks a free display
# number itself and reports it once it accepts connections (-displayfd), so parallel test
# runs (and other users' servers) cannot race for a display; -noreset keeps it from
# resetting (and refusing connections meanwhile) each time its last client disconnects.
# Exit status: the command's.
set -u
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
Xvfb -displayfd 3 -screen 0 320x240x24 -nolisten tcp -noreset 3>"$tmp/display" 2>"$tmp/xvfb.log" &
server=$!
i=0
while [ ! -s "$tmp/display" ]; do
    i=$((i + 1))
    if [ $i -gt 200 ] || ! kill -0 "$server" 2>/dev/null; then
        echo "run_with_xvfb: Xvfb did not start:" >&2
        cat "$tmp/xvfb.log" >&2
        kill "$server" 2>/dev/null
        exit 1
    fi
    sleep 0.05
done
DISPLAY=":$(cat "$tmp/display")" "$@"
status=$?
if [ $status -ne 0 ]; then
    echo "run_with_xvfb: display :$(cat "$tmp/display"); Xvfb log:" >&2
    cat "$tmp/xvfb.log" >&2
    if kill -0 "$server" 2>/dev/null; then echo "run_with_xvfb: server alive" >&2; else echo "run_with_xvfb: server dead" >&2; fi
    ls -la /tmp/.X11-unix >&2
fi
kill "$server" 2>/dev/null
wait "$server" 2>/dev/null
exit $status
