// Finds and loads libcpgait_footage.so once (cpgait/video/footage.h).
#include <dlfcn.h>
#include <unistd.h>

#include <climits>
#include <cstdlib>
#include <filesystem>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "cpgait/video/footage.h"

namespace cpgait::video {
namespace {

std::string executable_dir() {
  char buf[PATH_MAX];
  const ssize_t n = ::readlink("/proc/self/exe", buf, sizeof buf - 1);
  return n > 0 ? std::filesystem::path(std::string(buf, static_cast<std::size_t>(n))).parent_path().string() : std::string();
}

const FootageFunctions* load() {
  std::vector<std::string> candidates;
  if (const char* env = std::getenv("CPGAIT_FOOTAGE_MODULE"); env && *env) candidates.emplace_back(env);
  if (const std::string dir = executable_dir(); !dir.empty()) candidates.push_back(dir + "/libcpgait_footage.so");
  candidates.emplace_back(CPGAIT_FOOTAGE_MODULE_BUILT);
  std::string tried;
  for (const std::string& path : candidates) {
    if (!std::filesystem::exists(path)) {
      tried += "\n  " + path + ": not there";
      continue;
    }
    // RTLD_LOCAL: the module keeps its own copies of the capture code it was linked with.
    void* handle = ::dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (!handle) {
      tried += "\n  " + path + ": " + ::dlerror();
      continue;
    }
    auto* entry = reinterpret_cast<const FootageFunctions* (*)()>(::dlsym(handle, "cpgait_footage_functions"));
    if (entry) return entry();
    tried += "\n  " + path + ": no cpgait_footage_functions";
  }
  throw std::runtime_error("cannot load the footage module (OpenCV and AprilTag video support); tried:" + tried);
}

}  // namespace

const FootageFunctions& footage() {
  static std::once_flag once;
  static const FootageFunctions* functions = nullptr;
  std::call_once(once, [] { functions = load(); });
  return *functions;
}

}  // namespace cpgait::video
