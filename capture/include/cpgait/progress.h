#pragma once
// How a long-running stage reports progress and learns it was cancelled; the CLI prints, the service
// stores and streams. The default does nothing.
#include <string_view>

namespace cpgait {

class Progress {
 public:
  virtual ~Progress() = default;
  // fraction in [0, 1] of the current stage.
  virtual void report(double /*fraction*/, std::string_view /*message*/) {}
  virtual bool cancelled() const { return false; }
};

}  // namespace cpgait
