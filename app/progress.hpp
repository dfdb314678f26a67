#pragma once
// Progress lines on stderr and named phase timers for the CLI.
#include <chrono>
#include <map>
#include <mutex>
#include <string>
#include <vector>

namespace lambert::app {

// Prints "  form factors  42%  1 min 10 s, about 1 min 37 s left" on stderr: rewritten in place on a terminal, one
// line per 10% (and at least one a minute) otherwise; the final line gives the phase's whole time.
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
  size_t last_length_ = 0;
  std::chrono::steady_clock::time_point start_, last_print_{};
  std::mutex mutex_;
};

// Whether an update prints: on a terminal at most every 0.1 s (the line is rewritten); otherwise (a log file) at
// each new tenth of the work, or when kProgressHeartbeat seconds have passed since the last line, so that a phase of
// an hour still says every minute that it is running and how far it is.
constexpr double kProgressHeartbeat = 60;
bool progress_due(bool tty, int decile, int last_decile, double since_last_line);

// "4.2 s", "12 s", "3 min 05 s", "1 h 12 min" (rounded down; negative or NaN as 0).
std::string format_duration(double seconds);
// What follows a phase's percentage: the time elapsed, and once the phase has run for at least 3 s and done at least
// 1 % of its work, the time left at the rate so far ("1 min 10 s, about 1 min 37 s left"). fraction in [0, 1].
std::string progress_timing(double fraction, double elapsed_seconds);

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
