#include "lambert/mesh/types.hpp"

namespace lambert {

void check_failed(const char* condition, const char* file, int line, const std::string& what) {
  std::string f(file);
  if (const auto k = f.rfind("/src/"); k != std::string::npos) f = f.substr(f.rfind('/', k - 1) + 1);
  throw InternalError("check failed: " + std::string(condition) + " at " + f + ":" + std::to_string(line) +
                      (what.empty() ? std::string() : ": " + what));
}

}  // namespace lambert
