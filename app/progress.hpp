#pragma once
// Progress lines on stderr and named phase timers for the CLI.
#include <chrono>
#include <map>
#include <mutex>
#include <string>
#include <vector>

namespace lambert::app {

// Prints "  form factors  42%" on stderr: rewritten in place on a terminal, one line per 10% otherwise.
class Progress {
 public:
  Progress(std::string phase, bool enabled);
  ~Progress();
  void update(double fraction);        // thread-safe, rate-limited
  void note(const std::string& text);  // free text after the percentage (e.g. "iter 12  res 3e-5")
  void done();

 private:
  void print(double fraction, bool final_line);
  std::string phase_;
  bool enabled_, tty_, finished_ = false;
  int last_decile_ = -1;
  std::string note_;
  std::chrono::steady_clock::time_point last_print_{};
  std::mutex mutex_;
};

// Wall-clock time per named phase, in the order the phases ran.
class PhaseTimer {
 public:
  void start(const std::string& phase);
  void stop();
  double seconds(const std::string& phase) const;
  double total() const;
  const std::vector<std::pair<std::string, double>>& phases() const { return phases_; }

 private:
  std::vector<std::pair<std::string, double>> phases_;
  std::string current_;
  std::chrono::steady_clock::time_point t0_;
};

}  // namespace lambert::app
