# Sourced by the tests/mpi scripts, which set $mpiexec and $ranks first.
# run_on N COMMAND...: COMMAND on N ranks (as root, more ranks than cores); run COMMAND...: on $ranks.
run_on() {
  local n=$1
  shift
  "$mpiexec" -n "$n" --allow-run-as-root --oversubscribe "$@"
}
run() { run_on "$ranks" "$@"; }
# by_pair FILE: the pair lines of a clash output (its summary line dropped), sorted by (a, b) as numbers.
by_pair() {
  python3 -c '
import json, sys
lines = [l for l in open(sys.argv[1]) if "\"a\": " in l[:8]]
lines.sort(key=lambda l: (json.loads(l)["a"], json.loads(l)["b"]))
sys.stdout.write("".join(lines))' "$1"
}
