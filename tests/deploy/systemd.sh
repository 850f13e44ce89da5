#!/usr/bin/env bash
# deploy/systemd checked without booting anything: systemd-analyze verify (with ExecStart pointed at the built
# binary) must print nothing, for the optional socket unit too (which must listen where TESSERA_LISTEN says by
# default), systemd-sysusers must accept the user file, every `tessera` flag in ExecStart must be one the binary's
# --help lists, every variable ExecStart uses must come from the unit, its /etc/default file or a
# directory/credential setting of the unit, and the worker must stop on a single SIGTERM with time to finish a tile.
# A self-test first breaks the units in known ways and expects each to be caught. Arguments: TESSERA SOURCE_DIR.
set -euo pipefail
TESSERA=$(realpath "$1")
SRC=$(realpath "$2")
fail() { echo "FAIL: $*" >&2; exit 1; }
for tool in systemd-analyze systemd-sysusers; do
  command -v "$tool" >/dev/null || fail "'$tool' not found: install Debian's systemd"
done
WORK=$(mktemp -d "${TMPDIR:-/tmp}/tessera-systemd-test.XXXXXX")
trap 'rm -rf "$WORK"' EXIT

# check_units DIR: prints one line per problem with the units in DIR (nothing when they are right).
check_units() {
  local dir=$1 unit name sub flag var out
  for unit in "$dir"/tessera-coordinator.service "$dir"/tessera-worker.service; do
    name=$(basename "$unit" .service)
    [ -f "$unit" ] || { echo "$name: missing"; continue; }
    mkdir -p "$dir/verify"
    sed "s#/usr/bin/tessera#$TESSERA#g" "$unit" >"$dir/verify/$name.service"
    out=$(cd "$dir/verify" && systemd-analyze verify "$dir/verify/$name.service" 2>&1) || echo "$name: verify failed"
    [ -z "$out" ] || echo "$name: systemd-analyze verify: $out"
    # ExecStart as one line (continuations joined).
    local exec
    exec=$(sed -e ':a' -e '/\\$/N; s/\\\n//; ta' "$unit" | sed -n 's/^ExecStart=//p')
    [ -n "$exec" ] || { echo "$name: no ExecStart"; continue; }
    sub=$(awk '{print $2}' <<<"$exec")
    local help
    help=$("$TESSERA" "$sub" --help 2>/dev/null) || echo "$name: tessera $sub --help failed"
    for flag in $(grep -oE -- '(^| )--[a-z][a-z0-9-]*' <<<"$exec"); do
      grep -qE -- "(^|[ ,])$flag([ =,]|$)" <<<"$help" && continue
      echo "$name: tessera $sub has no flag $flag"
    done
    local default_file="$dir/$name.default"
    for var in $(grep -oE '\$\{?[A-Z_]+' <<<"$exec" | tr -d '${'); do
      case $var in
        STATE_DIRECTORY) grep -q '^StateDirectory=' "$unit" || echo "$name: uses \$STATE_DIRECTORY without StateDirectory=" ;;
        CACHE_DIRECTORY) grep -q '^CacheDirectory=' "$unit" || echo "$name: uses \$CACHE_DIRECTORY without CacheDirectory=" ;;
        CREDENTIALS_DIRECTORY)
          for cred in $(grep -oE 'CREDENTIALS_DIRECTORY\}/[a-z-]+' <<<"$exec" | cut -d/ -f2); do
            grep -q "^LoadCredential=$cred:" "$unit" || echo "$name: credential $cred is not loaded (LoadCredential=)"
          done ;;
        *) grep -q "^Environment=$var=" "$unit" || grep -q "^$var=" "$default_file" 2>/dev/null ||
             echo "$name: \$$var is set neither in the unit nor in $name.default" ;;
      esac
    done
  done
  # The optional socket unit: verified beside its service, listening where the service would by default.
  local socket=$dir/tessera-coordinator.socket
  if [ -f "$socket" ]; then
    cp "$socket" "$dir/verify/"
    out=$(cd "$dir/verify" && systemd-analyze verify "$dir/verify/tessera-coordinator.socket" 2>&1) ||
      echo "tessera-coordinator.socket: verify failed"
    [ -z "$out" ] || echo "tessera-coordinator.socket: systemd-analyze verify: $out"
    local stream listen
    stream=$(sed -n 's/^ListenStream=//p' "$socket")
    listen=$(sed -n 's/^TESSERA_LISTEN=//p' "$dir/tessera-coordinator.default")
    [ "$stream" = "$listen" ] || echo "tessera-coordinator.socket: ListenStream=$stream is not TESSERA_LISTEN=$listen"
  else
    echo "tessera-coordinator.socket: missing"
  fi
  # TLS: the coordinator serves HTTPS and reloads its certificate on `systemctl reload`; the worker's URL is
  # https:// and it is told which CA to trust.
  local coord=$dir/tessera-coordinator.service
  grep -q -- '--tls-cert ' "$coord" && grep -q -- '--tls-key ' "$coord" || echo "tessera-coordinator: no --tls-cert/--tls-key"
  grep -qx 'ExecReload=/bin/kill -HUP $MAINPID' "$coord" || echo "tessera-coordinator: ExecReload must send SIGHUP"
  grep -q '^TESSERA_COORDINATOR=https://' "$dir/tessera-worker.default" || echo "tessera-worker: the URL is not https://"
  grep -q -- '--ca-file ' "$dir/tessera-worker.service" || echo "tessera-worker: no --ca-file"
  local worker=$dir/tessera-worker.service
  grep -qx 'KillSignal=SIGTERM' "$worker" || echo "tessera-worker: KillSignal must be SIGTERM (finish the tile, exit 0)"
  grep -qx 'KillMode=mixed' "$worker" || echo "tessera-worker: KillMode must be mixed (one SIGTERM to the worker only)"
  local stop
  stop=$(sed -n 's/^TimeoutStopSec=//p' "$worker")
  [[ "$stop" =~ ^[0-9]+$ ]] && [ "$stop" -ge 120 ] || echo "tessera-worker: TimeoutStopSec ($stop) below 120 s"
  out=$(mkdir -p "$dir/root/etc" && touch "$dir/root/etc/passwd" "$dir/root/etc/group" &&
        systemd-sysusers --root="$dir/root" --dry-run "$dir/tessera.sysusers" 2>&1) || echo "sysusers: $out"
  grep -q "Creating user 'tessera'" <<<"$out" || echo "sysusers: does not create the tessera user: $out"
  grep -q '^User=tessera' "$dir/tessera-coordinator.service" || echo "tessera-coordinator: not run as tessera"
  return 0
}

# Self-test: each mutation (file, sed expression, expected fragment) must be reported.
mutations=(
  "tessera-worker.service|s/^TimeoutStopSec=600/TimeoutStopSecs=600/|Unknown key"
  "tessera-worker.service|s/^TimeoutStopSec=600/TimeoutStopSec=30/|below 120"
  "tessera-worker.service|s/^KillMode=mixed/KillMode=control-group/|KillMode must be mixed"
  "tessera-worker.service|s/--cache /--cache-dir /|has no flag --cache-dir"
  "tessera-worker.service|s/--token-file /--token-path /|has no flag --token-path"
  "tessera-coordinator.service|s/--client-token-file /--client-token /|has no flag --client-token"
  "tessera-worker.service|s/^CacheDirectory=tessera/#/|without CacheDirectory"
  "tessera-coordinator.service|s/^LoadCredential=worker-token/#/|credential worker-token is not loaded"
  "tessera-coordinator.service|s/{TESSERA_LISTEN}/{TESSERA_LISTN}/|TESSERA_LISTN is set neither"
  "tessera.sysusers|s/nologin/nologin extra/|sysusers"
  "tessera-coordinator.service|s/--tls-key \${TESSERA_TLS_KEY}//|no --tls-cert/--tls-key"
  "tessera-coordinator.service|s/^ExecReload=.*/ExecReload=/|ExecReload must send SIGHUP"
  "tessera-coordinator.default|s/^TESSERA_TLS_CERT=.*//|TESSERA_TLS_CERT is set neither"
  "tessera-worker.default|s#^TESSERA_COORDINATOR=https#TESSERA_COORDINATOR=http#|URL is not https"
  "tessera-coordinator.socket|s/^Backlog=/Backlogs=/|Unknown key"
  "tessera-coordinator.socket|s/^ListenStream=0.0.0.0:8470/ListenStream=0.0.0.0:8471/|is not TESSERA_LISTEN"
)
for m in "${mutations[@]}"; do
  IFS='|' read -r file expr expected <<<"$m"
  rm -rf "$WORK/m" && cp -r "$SRC/deploy/systemd" "$WORK/m"
  before=$(md5sum <"$WORK/m/$file")
  sed -i "$expr" "$WORK/m/$file"
  [ "$(md5sum <"$WORK/m/$file")" != "$before" ] || fail "self-test: '$expr' changed nothing in $file; update the mutation"
  report=$(check_units "$WORK/m")
  grep -qF -- "$expected" <<<"$report" || fail "self-test: '$expr' on $file was not caught (report: ${report:-empty})"
done
echo "self-test: all ${#mutations[@]} deliberate mistakes were caught"

rm -rf "$WORK/real" && cp -r "$SRC/deploy/systemd" "$WORK/real"
report=$(check_units "$WORK/real")
[ -z "$report" ] || fail "$report"
echo "PASS: systemd units verified (systemd $(systemd --version | awk 'NR==1{print $2}'))"
