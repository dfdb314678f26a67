#pragma once
// Internal helpers shared by the scene readers and writers (not installed).
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "lambert/mesh/soup.hpp"

namespace lambert::io::detail {

[[noreturn]] void fail(const std::string& file, int line, const std::string& what);

// Whole file as bytes. Returns false and sets `error` (strerror) when it cannot be read.
bool try_read_file(const std::string& path, std::string& out, std::string& error);
// Same, throwing InputError "PATH: cannot read file: REASON".
std::string read_file(const std::string& path);

// Splits text into lines (\n or \r\n). Optionally joins lines ending in '\' (OBJ/MTL) and cuts
// '#' comments. `line` is the 1-based number of the first physical line of the returned line.
class LineReader {
 public:
  LineReader(std::string_view text, bool continuation, bool comments)
      : text_(text), continuation_(continuation), comments_(comments) {
    if (text_.substr(0, 3) == "\xEF\xBB\xBF") pos_ = 3;  // UTF-8 byte order mark
  }
  bool next(std::string_view& out, int& line);
  int last_line() const { return next_line_ - 1; }  // last physical line read so far
  std::size_t offset() const { return pos_; }       // byte offset after the last line read

 private:
  std::string_view raw_line();
  std::string_view text_;
  std::size_t pos_ = 0;
  int next_line_ = 1;
  bool continuation_, comments_;
  std::string joined_;
};

void split(std::string_view s, std::vector<std::string_view>& tokens);  // on blanks
std::string_view trim(std::string_view s);
std::string lower(std::string_view s);
std::string quote(std::string_view s);  // 'text' for messages, shortened if very long

enum class NumStatus { ok, malformed, out_of_range, not_finite };
NumStatus parse_double(std::string_view s, double& out);     // whole token, optional leading '+'
NumStatus parse_integer(std::string_view s, long long& out);  // whole token, optional sign
bool integer_syntax(std::string_view s);                     // [+-]digits
// Finite double or InputError at file:line: "malformed number 'x' for WHAT; expected ...".
double finite_number(std::string_view tok, const std::string& file, int line, const std::string& what);

std::string format_double(double v);  // shortest decimal that reads back to exactly v

// 8-bit colour channel: true and k when v == k / 255.0 exactly, 0 <= k <= 255.
bool byte_value(double v, int& k);
std::string colour_material_name(const RGB& c);  // "color_R_G_B"
// Index of the colour material for c, added to soup (defined_at = where) on first use.
int colour_material(mesh::PolygonSoup& soup, std::unordered_map<std::string, int>& by_name, const RGB& c,
                    const SourceLoc& where);

// Writes content to path via a temporary file in the same directory and a rename.
void write_file_atomic(const std::string& path, const std::string& content);

}  // namespace lambert::io::detail
