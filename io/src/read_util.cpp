#include "read_util.hpp"

#include "lambert/io/atomic_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>

namespace lambert::io::detail {

void fail(const std::string& file, int line, const std::string& what) {
  throw InputError(SourceLoc{file, line}.str() + ": " + what);
}

bool try_read_file(const std::string& path, std::string& out, std::string& error) {
  // Regular files only: a FIFO would block forever and a device (/dev/zero) never ends. O_NONBLOCK keeps
  // open() itself from blocking on a FIFO without a writer; the size read is the size fstat reports.
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    error = std::strerror(errno);
    return false;
  }
  std::unique_ptr<int, void (*)(int*)> guard(new int(fd), [](int* p) {
    ::close(*p);
    delete p;
  });
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    error = std::strerror(errno);
    return false;
  }
  if (!S_ISREG(st.st_mode)) {
    error = S_ISDIR(st.st_mode)    ? std::strerror(EISDIR)
            : S_ISFIFO(st.st_mode) ? "it is a FIFO (named pipe); expected a regular file"
            : S_ISCHR(st.st_mode) || S_ISBLK(st.st_mode) ? "it is a device; expected a regular file"
                                                          : "not a regular file";
    return false;
  }
  const int flags = ::fcntl(fd, F_GETFL);
  if (flags >= 0) ::fcntl(fd, F_SETFL, flags & ~O_NONBLOCK);
  out.clear();
  out.reserve(static_cast<std::size_t>(st.st_size));
  char buf[1 << 16];
  // At most the size fstat reported (a file growing while read is not followed).
  std::size_t left = static_cast<std::size_t>(st.st_size);
  while (left > 0) {
    const ssize_t n = ::read(fd, buf, std::min(left, sizeof buf));
    if (n < 0) {
      if (errno == EINTR) continue;
      error = std::strerror(errno);
      return false;
    }
    if (n == 0) break;
    out.append(buf, static_cast<std::size_t>(n));
    left -= static_cast<std::size_t>(n);
  }
  return true;
}

std::string read_file(const std::string& path) {
  std::string text, error;
  if (!try_read_file(path, text, error)) throw InputError(path + ": cannot read file: " + error);
  return text;
}

std::string_view LineReader::raw_line() {
  std::size_t end = text_.find('\n', pos_);
  if (end == std::string_view::npos) end = text_.size();
  std::string_view l = text_.substr(pos_, end - pos_);
  pos_ = end < text_.size() ? end + 1 : end;
  ++next_line_;
  if (!l.empty() && l.back() == '\r') l.remove_suffix(1);
  return l;
}

bool LineReader::next(std::string_view& out, int& line) {
  if (pos_ >= text_.size()) return false;
  line = next_line_;
  out = raw_line();
  if (continuation_ && !out.empty() && out.back() == '\\') {
    joined_.assign(out.substr(0, out.size() - 1));
    while (pos_ < text_.size()) {
      std::string_view more = raw_line();
      bool again = !more.empty() && more.back() == '\\';
      if (again) more.remove_suffix(1);
      joined_ += ' ';
      joined_ += more;
      if (!again) break;
    }
    out = joined_;
  }
  if (comments_) {
    std::size_t hash = out.find('#');
    if (hash != std::string_view::npos) out = out.substr(0, hash);
  }
  return true;
}

static bool blank(char c) { return c == ' ' || c == '\t' || c == '\v' || c == '\f' || c == '\r'; }

void split(std::string_view s, std::vector<std::string_view>& tokens) {
  tokens.clear();
  std::size_t i = 0, n = s.size();
  while (i < n) {
    while (i < n && blank(s[i])) ++i;
    std::size_t start = i;
    while (i < n && !blank(s[i])) ++i;
    if (i > start) tokens.push_back(s.substr(start, i - start));
  }
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && blank(s.front())) s.remove_prefix(1);
  while (!s.empty() && blank(s.back())) s.remove_suffix(1);
  return s;
}

std::string lower(std::string_view s) {
  std::string r(s);
  for (char& c : r) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return r;
}

std::string quote(std::string_view s) {
  bool cut = s.size() > 40;
  std::string r;
  r.reserve(45);
  r.push_back('\'');
  r.append(cut ? s.substr(0, 37) : s);
  if (cut) r.append("...");
  r.push_back('\'');
  return r;
}

NumStatus parse_double(std::string_view s, double& out) {
  if (s.size() > 1 && s[0] == '+' && s[1] != '-' && s[1] != '+') s.remove_prefix(1);  // from_chars rejects '+'
  if (s.empty()) return NumStatus::malformed;
  auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), out);
  if (ptr != s.data() + s.size()) return NumStatus::malformed;
  if (ec == std::errc::result_out_of_range) return NumStatus::out_of_range;
  if (ec != std::errc()) return NumStatus::malformed;
  return std::isfinite(out) ? NumStatus::ok : NumStatus::not_finite;
}

NumStatus parse_integer(std::string_view s, long long& out) {
  if (s.size() > 1 && s[0] == '+' && s[1] != '-' && s[1] != '+') s.remove_prefix(1);
  if (s.empty()) return NumStatus::malformed;
  auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), out);
  if (ptr != s.data() + s.size()) return NumStatus::malformed;
  if (ec == std::errc::result_out_of_range) return NumStatus::out_of_range;
  if (ec != std::errc()) return NumStatus::malformed;
  return NumStatus::ok;
}

bool integer_syntax(std::string_view s) {
  if (!s.empty() && (s[0] == '+' || s[0] == '-')) s.remove_prefix(1);
  if (s.empty()) return false;
  for (char c : s)
    if (c < '0' || c > '9') return false;
  return true;
}

double finite_number(std::string_view tok, const std::string& file, int line, const std::string& what) {
  double v = 0;
  switch (parse_double(tok, v)) {
    case NumStatus::ok:
      return v;
    case NumStatus::malformed:
      fail(file, line, "malformed number " + quote(tok) + " for " + what + "; expected a decimal number");
    case NumStatus::out_of_range:
      fail(file, line, "number " + quote(tok) + " for " + what + " is out of the range of double");
    case NumStatus::not_finite:
      break;
  }
  fail(file, line, what + " is " + quote(tok) + " (not finite); expected a finite number");
}

std::string format_double(double v) {
  char buf[40];
  auto r = std::to_chars(buf, buf + sizeof buf, v);  // shortest exact round trip
  return std::string(buf, r.ptr);
}

bool byte_value(double v, int& k) {
  double r = std::round(v * 255.0);
  if (!(r >= 0 && r <= 255) || r / 255.0 != v) return false;
  k = static_cast<int>(r);
  return true;
}

std::string colour_material_name(const RGB& c) {
  std::string name = "color";
  for (int i = 0; i < 3; ++i) {
    int k;
    name += '_';
    if (byte_value(c[i], k)) {
      name += std::to_string(k);
    } else {
      std::string s = format_double(c[i]);
      // keep decimals apart from the 0..255 integers (2.0 is not 2/255)
      if (s.find_first_of(".en") == std::string::npos) s += ".0";
      name += s;
    }
  }
  return name;
}

int colour_material(mesh::PolygonSoup& soup, std::unordered_map<std::string, int>& by_name, const RGB& c,
                    const SourceLoc& where) {
  std::string name = colour_material_name(c);
  auto it = by_name.find(name);
  if (it != by_name.end()) return it->second;
  mesh::Material m;
  m.name = name;
  m.reflectance = c;
  m.defined_at = where;
  soup.materials.push_back(m);
  int index = static_cast<int>(soup.materials.size()) - 1;
  by_name.emplace(std::move(name), index);
  return index;
}

void write_file_atomic(const std::string& path, const std::string& content) {
  write_file_atomically(path, [&](std::ostream& out) { out.write(content.data(), static_cast<std::streamsize>(content.size())); });
}

}  // namespace lambert::io::detail
