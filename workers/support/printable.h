// Text from outside (file names, paths, tokens) made safe to put in a message or a log line.
#pragma once
#include <string>
#include <string_view>

namespace mm::support {

// Double-quoted, control and non-ASCII bytes as \xNN, at most max_chars of the text ("..." after).
inline std::string printable(std::string_view text, std::size_t max_chars = 120) {
  static const char* hex = "0123456789abcdef";
  std::string s = "\"";
  for (std::size_t i = 0; i < text.size() && i < max_chars; ++i) {
    const auto c = static_cast<unsigned char>(text[i]);
    if (c >= 32 && c < 127 && c != '"' && c != '\\') {
      s += static_cast<char>(c);
    } else {
      s += "\\x";
      s += hex[c >> 4];
      s += hex[c & 15];
    }
  }
  if (text.size() > max_chars) s += "...";
  return s + "\"";
}

}  // namespace mm::support
