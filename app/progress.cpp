#include "progress.hpp"

#include <unistd.h>

#include <cmath>
#include <cstdio>

namespace lambert::app {

Progress::Progress(std::string phase, bool enabled)
    : phase_(std::move(phase)),
      enabled_(enabled),
      tty_(isatty(STDERR_FILENO) != 0),
      start_(std::chrono::steady_clock::now()) {}

std::string format_duration(double seconds) {
  const double t = std::isfinite(seconds) && seconds > 0 ? seconds : 0;
  const long long s = static_cast<long long>(t);
  char buf[48];
  if (t < 10) std::snprintf(buf, sizeof buf, "%.1f s", std::floor(t * 10) / 10);
  else if (s < 60) std::snprintf(buf, sizeof buf, "%lld s", s);
  else if (s < 3600) std::snprintf(buf, sizeof buf, "%lld min %02lld s", s / 60, s % 60);
  else std::snprintf(buf, sizeof buf, "%lld h %02lld min", s / 3600, (s % 3600) / 60);
  return buf;
}

std::string progress_timing(double fraction, double elapsed) {
  std::string out = format_duration(elapsed);
  if (elapsed >= 3 && fraction >= 0.01 && fraction < 1)
    out += ", about " + format_duration(elapsed * (1 - fraction) / fraction) + " left";
  return out;
}

bool progress_due(bool tty, int decile, int last_decile, double since_last_line) {
  if (tty) return since_last_line >= 0.1;
  return decile > last_decile || since_last_line >= kProgressHeartbeat;
}

Progress::~Progress() { done(); }

void Progress::note(const std::string& text) {
  std::lock_guard lock(mutex_);
  note_ = text;
}

void Progress::update(double fraction) {
  if (!enabled_) return;
  std::lock_guard lock(mutex_);
  if (finished_) return;
  const auto now = std::chrono::steady_clock::now();
  const int decile = static_cast<int>(fraction * 10);
  if (!progress_due(tty_, decile, last_decile_, std::chrono::duration<double>(now - last_print_).count())) return;
  last_print_ = now;
  last_decile_ = decile;
  print(fraction, false);
}

void Progress::print(double fraction, bool final_line) {
  const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  char head[64];
  std::snprintf(head, sizeof head, "  %-14s %3d%%  ", phase_.c_str(), static_cast<int>(fraction * 100 + 1e-9));
  std::string line = head + progress_timing(final_line ? 1.0 : fraction, elapsed);
  if (!note_.empty()) line += "  " + note_;
  // On a terminal the line is rewritten in place: padded to the last one's length, so nothing of it is left behind.
  const size_t len = line.size();
  if (tty_ && line.size() < last_length_) line.append(last_length_ - line.size(), ' ');
  last_length_ = len;
  std::fprintf(stderr, "%s%s%s", tty_ ? "\r" : "", line.c_str(), (final_line || !tty_) ? "\n" : "");
  std::fflush(stderr);
}

void Progress::done() {
  if (!enabled_) return;
  std::lock_guard lock(mutex_);
  if (finished_) return;
  finished_ = true;
  if (tty_ || last_decile_ < 10) print(1.0, true);
}

void PhaseTimer::start(const std::string& phase) {
  if (!current_.empty()) stop();
  current_ = phase;
  t0_ = std::chrono::steady_clock::now();
}

void PhaseTimer::stop() {
  if (current_.empty()) return;
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0_).count();
  phases_.emplace_back(current_, s);
  current_.clear();
}

double PhaseTimer::seconds(const std::string& phase) const {
  double s = 0;
  for (const auto& [name, t] : phases_)
    if (name == phase) s += t;
  return s;
}

double PhaseTimer::total() const {
  double s = 0;
  for (const auto& p : phases_) s += p.second;
  return s;
}

}  // namespace lambert::app
