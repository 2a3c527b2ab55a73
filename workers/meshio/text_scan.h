// Small, strict scanning helpers shared by the format parsers (internal to meshio).
// Numbers go through std::from_chars: locale-independent, exact for doubles, and it reports
// any trailing junk, so "1.0x" is an error instead of a silent 1.0.
#pragma once
#include <charconv>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace mm::scan {

// Whole token must be a number; a leading '+' is accepted. NaN/Inf parse (callers reject them
// with a message that names the value rather than calling it malformed).
inline bool to_double(std::string_view t, double& out) {
  if (!t.empty() && t.front() == '+') t.remove_prefix(1);
  if (t.empty()) return false;
  auto r = std::from_chars(t.data(), t.data() + t.size(), out);
  return r.ec == std::errc() && r.ptr == t.data() + t.size();
}

inline bool to_int64(std::string_view t, long long& out) {
  if (!t.empty() && t.front() == '+') t.remove_prefix(1);
  if (t.empty()) return false;
  auto r = std::from_chars(t.data(), t.data() + t.size(), out);
  return r.ec == std::errc() && r.ptr == t.data() + t.size();
}

// Shown in error messages: at most 40 characters, non-printable bytes escaped.
inline std::string quote(std::string_view t) {
  std::string s = "\"";
  for (size_t i = 0; i < t.size() && i < 40; ++i) {
    unsigned char c = static_cast<unsigned char>(t[i]);
    if (c >= 32 && c < 127) {
      s += static_cast<char>(c);
    } else {
      static const char* hex = "0123456789abcdef";
      s += "\\x";
      s += hex[c >> 4];
      s += hex[c & 15];
    }
  }
  if (t.size() > 40) s += "...";
  return s + "\"";
}

// Whitespace-separated tokens with line numbers (1-based) for messages.
class Tokens {
 public:
  explicit Tokens(std::string_view text, size_t start = 0, int line = 1)
      : text_(text), pos_(start), line_(line) {}
  // Next token, or empty at end of input. line() is the line of the returned token.
  std::string_view next() {
    skip_space();
    size_t b = pos_;
    while (pos_ < text_.size() && !is_space(text_[pos_])) ++pos_;
    return text_.substr(b, pos_ - b);
  }
  // The rest of the current line (used for free-text names such as "solid <name>").
  std::string_view rest_of_line() {
    size_t b = pos_;
    while (pos_ < text_.size() && text_[pos_] != '\n') ++pos_;
    return text_.substr(b, pos_ - b);
  }
  int line() const { return tok_line_; }
  size_t pos() const { return pos_; }

 private:
  static bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\f' || c == '\v'; }
  void skip_space() {
    while (pos_ < text_.size() && is_space(text_[pos_])) {
      if (text_[pos_] == '\n') ++line_;
      ++pos_;
    }
    tok_line_ = line_;
  }
  std::string_view text_;
  size_t pos_;
  int line_;
  int tok_line_ = 1;
};

// Lines without their terminator ("\n" or "\r\n"), 1-based numbers.
class Lines {
 public:
  explicit Lines(std::string_view text) : text_(text) {}
  bool next(std::string_view& line) {
    if (pos_ >= text_.size()) return false;
    size_t e = text_.find('\n', pos_);
    if (e == std::string_view::npos) e = text_.size();
    line = text_.substr(pos_, e - pos_);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    pos_ = e + 1;
    ++number_;
    return true;
  }
  int number() const { return number_; }
  // Where the next line starts (past the end after the last line).
  size_t offset() const { return pos_; }

 private:
  std::string_view text_;
  size_t pos_ = 0;
  int number_ = 0;
};

// Splits one line into whitespace-separated tokens, stopping at a '#' comment.
inline void split(std::string_view line, std::vector<std::string_view>& out) {
  out.clear();
  auto space = [](char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v'; };
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && space(line[i])) ++i;
    if (i >= line.size() || line[i] == '#') break;
    size_t b = i;
    while (i < line.size() && !space(line[i])) ++i;
    out.push_back(line.substr(b, i - b));
  }
}

}  // namespace mm::scan
