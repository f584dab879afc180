#include "common/lcm/multicast_route.hpp"

#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <sstream>

namespace inertia {

bool has_multicast_route() {
  std::ifstream in("/proc/net/route");
  std::string line;
  std::getline(in, line);  // header
  while (std::getline(in, line)) {
    std::istringstream ss(line);
    std::string iface, dest, gateway, flags, refcnt, use, metric, mask;
    if (!(ss >> iface >> dest >> gateway >> flags >> refcnt >> use >> metric >> mask)) continue;
    // Little-endian hex: 224.0.0.0 is 000000E0. A route covers it when (224.0.0.0 & mask) == dest.
    const auto d = static_cast<std::uint32_t>(std::stoul(dest, nullptr, 16));
    const auto m = static_cast<std::uint32_t>(std::stoul(mask, nullptr, 16));
    if ((0x000000E0u & m) == d) return true;
  }
  return false;
}

std::string lcm_url(const std::string& explicit_url) {
  if (!explicit_url.empty()) return explicit_url;
  const char* env = std::getenv("LCM_DEFAULT_URL");
  return env != nullptr ? env : "";
}

bool is_udpm(const std::string& url) { return url.empty() || url.rfind("udpm://", 0) == 0; }

}  // namespace inertia
