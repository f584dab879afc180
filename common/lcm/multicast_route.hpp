#pragma once
// LCM's UDP multicast provider refuses to start on a host without a route for 224.0.0.0/4, even
// when every peer is on this host. Both the daemon and `inertia-analyze online`
// check it first, so the user reads how to fix it instead of LCM's bare failure.
#include <string>

namespace inertia {

/// True when /proc/net/route has a route covering 224.0.0.0 (a default route does).
bool has_multicast_route();

/// The LCM URL to use: `explicit_url`, else $LCM_DEFAULT_URL, else "" (LCM's default udpm).
std::string lcm_url(const std::string& explicit_url);

/// True when `url` (as lcm_url returns it) is the UDP multicast provider.
bool is_udpm(const std::string& url);

/// The message that says how to add the route.
inline constexpr const char* kMulticastRouteFix =
    "LCM needs a multicast route and this host has none (no 224.0.0.0/4 and no default route).\n"
    "  fix: ip link set lo multicast on && ip route add 224.0.0.0/4 dev lo";

}  // namespace inertia
