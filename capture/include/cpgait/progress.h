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

// A part of a parent's progress: its fractions [0, 1] reported as [begin, end] of the parent's, so a
// stage of several long steps rises through all of them. Cancellation passes through.
class ProgressShare : public Progress {
 public:
  ProgressShare(Progress* parent, double begin, double end) : parent_(parent), begin_(begin), end_(end) {}
  void report(double fraction, std::string_view message) override {
    if (parent_) parent_->report(begin_ + fraction * (end_ - begin_), message);
  }
  bool cancelled() const override { return parent_ && parent_->cancelled(); }

 private:
  Progress* parent_;
  double begin_, end_;
};

}  // namespace cpgait
