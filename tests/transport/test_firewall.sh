#!/usr/bin/env bash
# The firewall rules of docs/reliability.md (config/firewall/vslam-lcm.nft)
# on the wire (CTest transport.firewall): three network namespaces, the
# robot computer (eth0 on the home LAN, vslam0 to the robot's other
# computer), another host on the LAN and the robot's other computer. A
# listener bound as LCM binds (port 7667 on every address, the group joined)
# must hear the other robot computer's multicast and unicast and this
# computer's own ttl=0 datagrams, and must not hear a unicast datagram from
# the LAN host; without the rules it does (so the test can tell). Skips
# without root, ip netns or nft.
#
#   tests/transport/test_firewall.sh REPO_ROOT
set -euo pipefail
ROOT=$(cd "$1" && pwd)
RULES=$ROOT/config/firewall/vslam-lcm.nft
fail() { echo "FAIL: $*" >&2; exit 1; }
if [ "$(id -u)" -ne 0 ] || ! command -v nft >/dev/null; then
  echo "SKIP: needs root and nft (scripts/setup installs nftables)"
  exit 77
fi
ns=vslam-fw$$
host=$ns-host lan=$ns-lan robot=$ns-robot
cleanup() { for n in $host $lan $robot; do ip netns del "$n" 2>/dev/null || true; done; }
trap cleanup EXIT
for n in $host $lan $robot; do
  ip netns add "$n" 2>/dev/null || { echo "SKIP: ip netns add failed"; exit 77; }
  ip -n "$n" link set lo up
done
ip link add eth0 netns "$host" type veth peer name eth0 netns "$lan"
ip link add vslam0 netns "$host" type veth peer name vslam0 netns "$robot"
ip -n "$host" addr add 10.1.0.1/24 dev eth0
ip -n "$lan" addr add 10.1.0.2/24 dev eth0
ip -n "$host" addr add 10.2.0.1/24 dev vslam0
ip -n "$robot" addr add 10.2.0.2/24 dev vslam0
for pair in "$host eth0" "$lan eth0" "$host vslam0" "$robot vslam0"; do
  read -r n dev <<<"$pair"
  ip -n "$n" link set "$dev" up
done
ip -n "$host" route add default dev eth0  # the home LAN is the default route
ip -n "$host" route add 239.255.76.67/32 dev vslam0
ip -n "$robot" route add 239.255.76.67/32 dev vslam0
ip -n "$lan" route add 239.255.76.67/32 dev eth0

# Prints "ready" once bound and joined, then the tags of the datagrams it
# hears on port 7667 until "end" (this computer's own, sent last) and 0.3 s
# more, or 20 s. The senders wait for "ready": on a loaded CI machine Python
# took over 0.5 s to start, and the first datagram was lost.
listen() {
  ip netns exec "$host" /usr/bin/python3 -c '
import socket, struct, time
s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
s.bind(("", 7667))
s.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP,
             struct.pack("4s4s", socket.inet_aton("239.255.76.67"), socket.inet_aton("0.0.0.0")))
s.settimeout(0.2)
print("ready", flush=True)
end = time.time() + 20.0
while time.time() < end:
    try:
        tag = s.recv(100).decode()
    except socket.timeout:
        continue
    if tag == "end":
        end = min(end, time.time() + 0.3)
    else:
        print(tag, flush=True)
'
}
send() {  # NAMESPACE ADDRESS TTL TAG
  ip netns exec "$1" /usr/bin/python3 -c '
import socket, sys
s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
s.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, int(sys.argv[2]))
for _ in range(3):
    s.sendto(sys.argv[3].encode(), (sys.argv[1], 7667))
' "$2" "$3" "$4"
}
heard() {
  listen >"$work" &
  local pid=$! tries=0
  until grep -q '^ready$' "$work"; do
    ((++tries < 100)) || fail "the listener did not start in 10 s"
    sleep 0.1
  done
  send "$lan" 10.1.0.1 1 lan-unicast
  send "$robot" 239.255.76.67 1 robot-multicast
  send "$robot" 10.2.0.1 1 robot-unicast
  send "$host" 239.255.76.67 0 own-ttl0
  send "$host" 239.255.76.67 0 end
  wait "$pid"
  grep -v '^ready$' "$work" | sort -u | tr '\n' ' '
}
work=$(mktemp "${TMPDIR:-/tmp}/vslam-test-firewall.XXXXXX")
trap 'cleanup; rm -f "$work"' EXIT

without=$(heard)
[[ $without == *lan-unicast* ]] ||
  fail "without the rules the LAN host's datagram was not heard ($without): the test cannot tell"
ip netns exec "$host" nft -f "$RULES" || fail "nft refused $RULES"
with=$(heard)
for tag in robot-multicast robot-unicast own-ttl0; do
  [[ $with == *$tag* ]] || fail "with the rules, $tag was not heard (heard: $with)"
done
[[ $with != *lan-unicast* ]] || fail "with the rules, the LAN host's datagram was heard ($with)"
echo "without the rules: $without"
echo "with the rules:    $with"
echo "PASS: transport.firewall"
