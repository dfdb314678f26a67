#include "progress.hpp"

#include <unistd.h>

#include <cstdio>

namespace lambert::app {

Progress::Progress(std::string phase, bool enabled)
    : phase_(std::move(phase)), enabled_(enabled), tty_(isatty(STDERR_FILENO) != 0) {}

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
  if (tty_) {
    if (now - last_print_ < std::chrono::milliseconds(100)) return;
  } else if (decile <= last_decile_) {
    return;
  }
  last_print_ = now;
  last_decile_ = decile;
  print(fraction, false);
}

void Progress::print(double fraction, bool final_line) {
  std::fprintf(stderr, "%s  %-14s %3d%%  %s%s", tty_ ? "\r" : "", phase_.c_str(), static_cast<int>(fraction * 100 + 1e-9),
               note_.c_str(), (final_line || !tty_) ? "\n" : "");
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
