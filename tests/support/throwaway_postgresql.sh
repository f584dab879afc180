#!/usr/bin/env bash
# A throwaway PostgreSQL server for the record's tests: its own data folder, reached through a
# Unix socket in that folder only (no TCP port, so it cannot collide with another server or run),
# trust authentication for its one role, fsync off (nothing here outlives the test).
#   throwaway_postgresql.sh start DIR   prints the connection URL; exit 77 with the reason on
#                                       stderr when this machine has no server or cannot run one
#   throwaway_postgresql.sh stop DIR    stops it (immediate: the folder is removed next)
# PostgreSQL refuses to run as root: as root, the server runs as the postgres user that Debian's
# package creates, and DIR is handed to it.
set -euo pipefail
action="${1:?start|stop}"
dir="${2:?DIR}"

bin=""
for candidate in /usr/lib/postgresql/*/bin; do
  [[ -x "$candidate/initdb" && -x "$candidate/pg_ctl" ]] && bin="$candidate"
done
if [[ -z "$bin" ]]; then
  echo "no PostgreSQL server here (/usr/lib/postgresql/*/bin/initdb): apt install postgresql (cmake/debian-packages.txt lists it)" >&2
  exit 77
fi

as_server() {
  if [[ "$(id -u)" == 0 ]]; then
    runuser -u postgres -- "$@"
  else
    "$@"
  fi
}

case "$action" in
  start)
    if [[ "$(id -u)" == 0 ]] && ! id postgres >/dev/null 2>&1; then
      echo "running as root, and there is no postgres user to run the server as (PostgreSQL refuses root)" >&2
      exit 77
    fi
    mkdir -p "$dir/socket"
    [[ "$(id -u)" == 0 ]] && chown -R postgres: "$dir"
    if ! as_server "$bin/initdb" -D "$dir/data" -U inertia --auth=trust -E UTF8 --no-sync >"$dir/initdb.log" 2>&1; then
      echo "initdb failed: $(tail -n 3 "$dir/initdb.log")" >&2
      exit 77
    fi
    if ! as_server "$bin/pg_ctl" -D "$dir/data" -l "$dir/server.log" -w -t 60 \
        -o "-c listen_addresses='' -k $dir/socket -c fsync=off -c full_page_writes=off" start >/dev/null 2>&1; then
      echo "the server did not start: $(tail -n 3 "$dir/server.log" 2>/dev/null)" >&2
      exit 77
    fi
    echo "postgresql:///postgres?host=$dir/socket&user=inertia"
    ;;
  stop)
    [[ -d "$dir/data" ]] && as_server "$bin/pg_ctl" -D "$dir/data" -m immediate -w stop >/dev/null 2>&1 || true
    ;;
  *)
    echo "usage: $0 start|stop DIR" >&2
    exit 2
    ;;
esac
