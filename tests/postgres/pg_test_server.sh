#!/usr/bin/env bash
# A private PostgreSQL server for the tests, from the Debian package (no system service is touched):
#   pg_test_server.sh start STATE_DIR    initdb into a new temporary folder, start on a free port of
#                                        127.0.0.1 as an unprivileged user; writes STATE_DIR/url
#   pg_test_server.sh restart STATE_DIR  stop (fast) and start again on the same port and data
#   pg_test_server.sh stop STATE_DIR     stop it and remove its data
# Without the server package, start writes no url and says so; the tests that need it then skip.
set -euo pipefail
cmd=${1:?start, restart or stop}
state=${2:?state folder}
mkdir -p "$state"
bin=$(ls -d /usr/lib/postgresql/*/bin 2>/dev/null | sort -V | tail -1 || true)
as=()
[ "$(id -u)" -eq 0 ] && as=(setpriv --reuid=nobody --regid=nogroup --clear-groups)  # initdb refuses to run as root

ctl() { "${as[@]}" "$bin/pg_ctl" -D "$(cat "$state/pgdata")/db" "$@"; }

case "$cmd" in
start)
  [ -f "$state/pgdata" ] && "$0" stop "$state"
  rm -f "$state/url"
  if [ -z "$bin" ] || [ ! -x "$bin/initdb" ]; then
    echo "PostgreSQL server not installed (Debian package postgresql): the PostgreSQL tests skip"
    exit 0
  fi
  data=$(mktemp -d /tmp/cpgait-pg.XXXXXX)
  [ "$(id -u)" -eq 0 ] && chown nobody:nogroup "$data"
  echo "$data" > "$state/pgdata"
  "${as[@]}" "$bin/initdb" -D "$data/db" -U cpgait --auth=trust -E UTF8 --no-sync > "$data/initdb.log"
  # A port below the kernel's ephemeral range: a port in it can be taken at any moment as the local
  # end of some client connection (the tests make thousands), and a start there once failed with
  # "Address already in use". Another test's server may still take the same one first: then retry.
  low=$(cut -f1 /proc/sys/net/ipv4/ip_local_port_range 2>/dev/null || echo 32768)
  [ "$low" -gt 11000 ] || low=32768
  started=""
  for attempt in 1 2 3 4 5; do
    port=""
    for p in $(shuf -i 10000-$((low - 1)) -n 100); do
      if ! (exec 3<>"/dev/tcp/127.0.0.1/$p") 2>/dev/null; then port=$p; break; fi
    done
    [ -n "$port" ] || { echo "no free port"; exit 1; }
    if ctl -l "$data/server.log" -w -t 60 \
        -o "-p $port -k $data -c listen_addresses=127.0.0.1 -c max_connections=300 -c fsync=off" start > /dev/null; then
      started=1
      break
    fi
  done
  [ -n "$started" ] || { echo "pg_ctl could not start the server on 5 ports; see $data/server.log"; exit 1; }
  echo "$port" > "$state/port"
  echo "postgresql://cpgait@127.0.0.1:$port/postgres" > "$state/url"
  echo "PostgreSQL $("$bin/postgres" --version | awk '{print $3}') on 127.0.0.1:$port, data $data"
  ;;
restart)
  ctl -m fast -w stop > /dev/null
  port=$(cat "$state/port")
  data=$(cat "$state/pgdata")
  ctl -l "$data/server.log" -w -t 60 \
      -o "-p $port -k $data -c listen_addresses=127.0.0.1 -c max_connections=300 -c fsync=off" start > /dev/null
  ;;
stop)
  if [ -f "$state/pgdata" ]; then
    ctl -m immediate -w stop > /dev/null 2>&1 || true
    rm -rf "$(cat "$state/pgdata")"
  fi
  rm -f "$state/pgdata" "$state/url" "$state/port"
  ;;
*) echo "usage: $0 start|restart|stop STATE_DIR"; exit 2 ;;
esac
