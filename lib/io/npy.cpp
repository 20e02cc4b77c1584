// npy.cpp — .npy reading and writing, and the element-type helpers shared by the volume readers.
#include "io/npy.hpp"

#include <algorithm>
#include <cctype>
#include <climits>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <limits>

#include "io/files.hpp"
#include "ivr/error.hpp"
#include "ivr/volume_io.hpp"

namespace ivr {
namespace volfile {

std::size_t scalar_size(ScalarType type) {
  switch (type) {
    case ScalarType::uint8:
    case ScalarType::int8:
      return 1;
    case ScalarType::uint16:
    case ScalarType::int16:
      return 2;
    case ScalarType::uint32:
    case ScalarType::int32:
    case ScalarType::float32:
      return 4;
    case ScalarType::float64:
      return 8;
  }
  return 0;
}

const char* scalar_name(ScalarType type) {
  switch (type) {
    case ScalarType::uint8:
      return "uint8";
    case ScalarType::int8:
      return "int8";
    case ScalarType::uint16:
      return "uint16";
    case ScalarType::int16:
      return "int16";
    case ScalarType::uint32:
      return "uint32";
    case ScalarType::int32:
      return "int32";
    case ScalarType::float32:
      return "float32";
    case ScalarType::float64:
      return "float64";
  }
  return "?";
}

bool is_integer(ScalarType type) {
  return type != ScalarType::float32 && type != ScalarType::float64;
}

std::optional<ScalarType> parse_scalar_type(const std::string& name) {
  // Lower-case and collapse runs of blanks so "Unsigned  Char" matches "unsigned char".
  std::string key;
  for (char c : name) {
    if (std::isspace(static_cast<unsigned char>(c))) {
      if (!key.empty() && key.back() != ' ') key += ' ';
    } else {
      key += char(std::tolower(static_cast<unsigned char>(c)));
    }
  }
  if (!key.empty() && key.back() == ' ') key.pop_back();
  static const std::pair<const char*, ScalarType> kNames[] = {
      {"uint8", ScalarType::uint8},
      {"uint8_t", ScalarType::uint8},
      {"uchar", ScalarType::uint8},
      {"unsigned char", ScalarType::uint8},
      {"int8", ScalarType::int8},
      {"int8_t", ScalarType::int8},
      {"signed char", ScalarType::int8},
      {"uint16", ScalarType::uint16},
      {"uint16_t", ScalarType::uint16},
      {"ushort", ScalarType::uint16},
      {"unsigned short", ScalarType::uint16},
      {"unsigned short int", ScalarType::uint16},
      {"int16", ScalarType::int16},
      {"int16_t", ScalarType::int16},
      {"short", ScalarType::int16},
      {"short int", ScalarType::int16},
      {"signed short", ScalarType::int16},
      {"signed short int", ScalarType::int16},
      {"uint32", ScalarType::uint32},
      {"uint32_t", ScalarType::uint32},
      {"uint", ScalarType::uint32},
      {"unsigned int", ScalarType::uint32},
      {"int32", ScalarType::int32},
      {"int32_t", ScalarType::int32},
      {"int", ScalarType::int32},
      {"signed int", ScalarType::int32},
      {"float32", ScalarType::float32},
      {"float", ScalarType::float32},
      {"float64", ScalarType::float64},
      {"double", ScalarType::float64},
  };
  for (const auto& [n, t] : kNames)
    if (key == n) return t;
  return std::nullopt;
}

bool host_is_big_endian() {
  const std::uint16_t one = 1;
  unsigned char first;
  std::memcpy(&first, &one, 1);
  return first == 0;
}

std::size_t checked_count(const std::vector<std::size_t>& shape, std::size_t limit,
                          const std::string& path) {
  std::size_t count = 1;
  for (std::size_t n : shape) {
    if (n != 0 && count > limit / n) {
      std::string dims;
      for (std::size_t m : shape) dims += (dims.empty() ? "" : ", ") + std::to_string(m);
      throw Error(Status::invalid_argument, "array of shape (" + dims + ") has more than " +
                                                std::to_string(limit) + " elements: '" + path +
                                                "'");
    }
    count *= n;
  }
  return count;
}

namespace {

[[noreturn]] void fail(const std::string& path, const std::string& what) {
  throw Error(Status::io, what + ": '" + path + "'");
}

// One value of the header's Python dict literal.
struct PyValue {
  enum Kind { string, boolean, tuple, other } kind = other;
  std::string text;
  bool flag = false;
  std::vector<std::size_t> ints;
};

// Parses the header dict, e.g. {'descr': '<f4', 'fortran_order': False, 'shape': (3, 4), }.
class HeaderParser {
 public:
  HeaderParser(const std::string& text, const std::string& path) : s_(text), path_(path) {}

  std::vector<std::pair<std::string, PyValue>> parse_dict() {
    std::vector<std::pair<std::string, PyValue>> items;
    expect('{');
    while (true) {
      skip_blanks();
      if (peek() == '}') break;
      std::string key = parse_string();
      expect(':');
      PyValue value = parse_value();
      items.emplace_back(std::move(key), std::move(value));
      skip_blanks();
      if (peek() == ',') {
        ++pos_;
      } else if (peek() != '}') {
        bad("expected ',' or '}'");
      }
    }
    return items;
  }

 private:
  [[noreturn]] void bad(const std::string& why) {
    fail(path_, "malformed .npy header (" + why + " at character " + std::to_string(pos_) + ")");
  }
  void skip_blanks() {
    while (pos_ < s_.size() && std::isspace(static_cast<unsigned char>(s_[pos_]))) ++pos_;
  }
  char peek() { return pos_ < s_.size() ? s_[pos_] : '\0'; }
  void expect(char c) {
    skip_blanks();
    if (peek() != c) bad(std::string("expected '") + c + "'");
    ++pos_;
  }
  std::string parse_string() {
    skip_blanks();
    const char quote = peek();
    if (quote != '\'' && quote != '"') bad("expected a quoted string");
    const std::size_t end = s_.find(quote, pos_ + 1);
    if (end == std::string::npos) bad("unterminated string");
    std::string text = s_.substr(pos_ + 1, end - pos_ - 1);
    pos_ = end + 1;
    return text;
  }
  PyValue parse_value() {
    skip_blanks();
    PyValue v;
    const char c = peek();
    if (c == '\'' || c == '"') {
      v.kind = PyValue::string;
      v.text = parse_string();
    } else if (s_.compare(pos_, 4, "True") == 0 || s_.compare(pos_, 5, "False") == 0) {
      v.kind = PyValue::boolean;
      v.flag = s_[pos_] == 'T';
      pos_ += v.flag ? 4 : 5;
    } else if (c == '(') {
      v.kind = PyValue::tuple;
      ++pos_;
      while (true) {
        skip_blanks();
        if (peek() == ')') break;
        v.ints.push_back(parse_size());
        skip_blanks();
        if (peek() == ',') {
          ++pos_;
        } else if (peek() != ')') {
          bad("expected ',' or ')' in a tuple");
        }
      }
      ++pos_;
    } else if (c == '[') {
      // A list descr is a structured dtype; skip it (balanced brackets) and report it as such.
      v.kind = PyValue::other;
      int depth = 0;
      do {
        if (peek() == '[') ++depth;
        if (peek() == ']') --depth;
        if (peek() == '\0') bad("unterminated list");
        ++pos_;
      } while (depth > 0);
      v.text = "structured dtype";
    } else {
      bad("unexpected value");
    }
    return v;
  }
  std::size_t parse_size() {
    if (!std::isdigit(static_cast<unsigned char>(peek()))) bad("expected a non-negative integer");
    std::size_t n = 0;
    while (std::isdigit(static_cast<unsigned char>(peek()))) {
      const std::size_t digit = std::size_t(s_[pos_++] - '0');
      if (n > (std::numeric_limits<std::size_t>::max() - digit) / 10) bad("dimension too large");
      n = n * 10 + digit;
    }
    if (peek() == 'L') ++pos_;  // Python 2 longs
    return n;
  }

  const std::string& s_;
  const std::string& path_;
  std::size_t pos_ = 0;
};

// Maps a descr such as "<f4" or "|u1" to a type and byte order.
bool parse_descr(const std::string& descr, ScalarType* type, bool* big_endian) {
  if (descr.size() < 3) return false;
  const char order = descr[0];
  if (order != '<' && order != '>' && order != '|' && order != '=') return false;
  const std::string code = descr.substr(1);
  static const std::pair<const char*, ScalarType> kCodes[] = {
      {"f4", ScalarType::float32}, {"f8", ScalarType::float64}, {"u1", ScalarType::uint8},
      {"i1", ScalarType::int8},    {"u2", ScalarType::uint16},  {"i2", ScalarType::int16},
      {"u4", ScalarType::uint32},  {"i4", ScalarType::int32},
  };
  for (const auto& [c, t] : kCodes) {
    if (code == c) {
      *type = t;
      *big_endian = order == '>' || ((order == '=' || order == '|') && host_is_big_endian());
      return true;
    }
  }
  return false;
}

std::string shape_text(const std::vector<std::size_t>& shape) {
  std::string text = "(";
  for (std::size_t i = 0; i < shape.size(); ++i) text += (i ? ", " : "") + std::to_string(shape[i]);
  return text + (shape.size() == 1 ? ",)" : ")");
}

// Reorders Fortran-order elements (first index fastest) into C order (last index fastest).
std::vector<unsigned char> fortran_to_c(const unsigned char* src,
                                        const std::vector<std::size_t>& shape, std::size_t count,
                                        std::size_t elem) {
  std::vector<unsigned char> dst(count * elem);
  const std::size_t n = shape.size();
  if (count == 0 || n == 0) {
    std::copy(src, src + count * elem, dst.begin());
    return dst;
  }
  std::vector<std::size_t> stride(n), index(n, 0);
  stride[0] = 1;
  for (std::size_t k = 1; k < n; ++k) stride[k] = stride[k - 1] * shape[k - 1];
  std::size_t from = 0;
  for (std::size_t i = 0; i < count; ++i) {
    std::memcpy(dst.data() + i * elem, src + from * elem, elem);
    for (std::size_t k = n; k-- > 0;) {  // odometer over the C-order index, last axis fastest
      if (++index[k] < shape[k]) {
        from += stride[k];
        break;
      }
      from -= stride[k] * (shape[k] - 1);
      index[k] = 0;
    }
  }
  return dst;
}

}  // namespace

TypedArray read_npy(const std::string& path, const PlaneChooser& planes) {
  TypedArray a;
  // With `planes`, the header alone first (its length is in the preamble), the planes' bytes last.
  std::error_code size_error;
  const std::uintmax_t file_bytes = std::filesystem::file_size(path, size_error);
  const bool partial = bool(planes) && !size_error;
  if (partial) {
    a.bytes = read_binary_range(path, ".npy file", 0,
                                std::size_t(std::min<std::uintmax_t>(file_bytes, 12)));
    std::size_t end = a.bytes.size();
    if (end >= 10 && a.bytes[6] == 1) end = 10 + (std::size_t(a.bytes[8]) | std::size_t(a.bytes[9]) << 8);
    if (end >= 12 && (a.bytes[6] == 2 || a.bytes[6] == 3))
      end = 12 + (std::size_t(a.bytes[8]) | std::size_t(a.bytes[9]) << 8 |
                  std::size_t(a.bytes[10]) << 16 | std::size_t(a.bytes[11]) << 24);
    a.bytes = read_binary_range(path, ".npy file", 0,
                                std::size_t(std::min<std::uintmax_t>(file_bytes, end)));
  } else {
    a.bytes = read_binary_file(path, ".npy file");
  }
  const std::vector<unsigned char>& b = a.bytes;
  const std::size_t total = partial ? std::size_t(file_bytes) : b.size();
  static const unsigned char kMagic[6] = {0x93, 'N', 'U', 'M', 'P', 'Y'};
  if (b.size() < 6 || std::memcmp(b.data(), kMagic, 6) != 0)
    fail(path, "not a .npy file (bad magic, expected \\x93NUMPY)");
  if (b.size() < 8) fail(path, "truncated .npy header");
  const int major = b[6];
  std::size_t header_len = 0, start = 0;
  if (major == 1) {
    if (b.size() < 10) fail(path, "truncated .npy header");
    header_len = std::size_t(b[8]) | std::size_t(b[9]) << 8;
    start = 10;
  } else if (major == 2 || major == 3) {
    if (b.size() < 12) fail(path, "truncated .npy header");
    header_len = std::size_t(b[8]) | std::size_t(b[9]) << 8 | std::size_t(b[10]) << 16 |
                 std::size_t(b[11]) << 24;
    start = 12;
  } else {
    fail(path, "unsupported .npy format version " + std::to_string(major));
  }
  if (header_len > b.size() - start || header_len > total - start)
    fail(path, "truncated .npy header");
  const std::string header(b.begin() + std::ptrdiff_t(start),
                           b.begin() + std::ptrdiff_t(start + header_len));

  std::optional<PyValue> descr, fortran, shape;
  for (auto& [key, value] : HeaderParser(header, path).parse_dict()) {
    if (key == "descr") descr = value;
    if (key == "fortran_order") fortran = value;
    if (key == "shape") shape = value;
  }
  if (!descr || !fortran || !shape)
    fail(path, "malformed .npy header (needs 'descr', 'fortran_order' and 'shape')");
  if (fortran->kind != PyValue::boolean || shape->kind != PyValue::tuple)
    fail(path, "malformed .npy header (bad 'fortran_order' or 'shape')");
  if (descr->kind != PyValue::string || !parse_descr(descr->text, &a.type, &a.big_endian))
    fail(path, "unsupported .npy dtype '" + descr->text +
                   "' (supported: f4, f8, u1, i1, u2, i2, u4, i4 in either byte order)");
  a.shape = shape->ints;

  const std::size_t elem = scalar_size(a.type);
  const std::size_t avail = total - start - header_len;
  // Compare against the bytes present before multiplying by anything, so no shape overflows.
  std::size_t count = 1;
  bool too_big = false;
  if (std::find(a.shape.begin(), a.shape.end(), std::size_t(0)) != a.shape.end()) {
    count = 0;
  } else {
    for (std::size_t n : a.shape) {
      if (count > avail / n) {
        too_big = true;
        break;
      }
      count *= n;
    }
  }
  if (too_big || count * elem != avail) {
    const bool truncated = too_big || count * elem > avail;
    fail(path, std::string(truncated ? "truncated .npy" : "trailing bytes in .npy") +
                   " (data has " + std::to_string(avail) + " bytes but shape " +
                   shape_text(a.shape) + " of " + scalar_name(a.type) + " needs " +
                   (too_big ? "more" : std::to_string(count * elem)) + ")");
  }
  a.offset = start + header_len;
  if (partial && !fortran->flag && a.shape.size() == 3 && count > 0 && a.shape[0] <= INT_MAX) {
    const auto [first, last] = planes(int(a.shape[0]));
    if (first < 0 || last < first || std::size_t(last) >= a.shape[0])
      throw Error(Status::invalid_argument, "planes " + std::to_string(first) + ".." +
                                                std::to_string(last) + " of " +
                                                std::to_string(a.shape[0]) + ": '" + path + "'");
    const std::size_t plane = a.shape[1] * a.shape[2] * elem;
    a.bytes = read_binary_range(path, ".npy file", a.offset + std::size_t(first) * plane,
                                std::size_t(last - first + 1) * plane);
    a.offset = 0;
    a.first_plane = std::size_t(first);
    a.planes = last - first + 1;
    return a;
  }
  if (partial) {  // (Fortran order or not 3-D: the whole file, the planes cut by the caller)
    a.bytes = read_binary_file(path, ".npy file");
    if (a.bytes.size() != total) fail(path, "changed while it was read");
  }
  if (fortran->flag && a.shape.size() > 1) {
    a.bytes = fortran_to_c(a.bytes.data() + a.offset, a.shape, count, elem);
    a.offset = 0;
  }
  return a;
}

}  // namespace volfile

namespace {

// A little-endian .npy of float32 or float64 (T), through a temporary file and a rename.
template <class T>
void save_npy_as(const std::string& path, const std::vector<std::size_t>& shape, const T* data) {
  const std::size_t count =
      volfile::checked_count(shape, std::numeric_limits<std::size_t>::max() / sizeof(T), path);
  if (count != 0 && data == nullptr)
    throw Error(Status::invalid_argument, "no data given to write to .npy: '" + path + "'");
  std::string dict = std::string("{'descr': '") + (sizeof(T) == 8 ? "<f8" : "<f4") +
                     "', 'fortran_order': False, 'shape': (";
  for (std::size_t i = 0; i < shape.size(); ++i) dict += (i ? ", " : "") + std::to_string(shape[i]);
  dict += shape.size() == 1 ? ",), }" : "), }";
  // Version 1.0 has a 10-byte preamble; numpy pads the header with blanks so data is 64-aligned.
  const bool v2 = dict.size() + 1 + 10 + 64 > 65535;
  const std::size_t preamble = v2 ? 12 : 10;
  const std::size_t total = (preamble + dict.size() + 1 + 63) / 64 * 64;
  dict.append(total - preamble - dict.size() - 1, ' ');
  dict += '\n';
  std::string head = "\x93NUMPY";
  head += char(v2 ? 2 : 1);
  head += char(0);
  const std::size_t len = dict.size();
  head += char(len & 0xff);
  head += char((len >> 8) & 0xff);
  if (v2) {
    head += char((len >> 16) & 0xff);
    head += char((len >> 24) & 0xff);
  }
  head += dict;

  write_atomically(path, [&](const std::string& tmp) {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw Error(Status::io, "cannot open a temporary file to write .npy: '" + path + "'");
    out.write(head.data(), std::streamsize(head.size()));
    if (!volfile::host_is_big_endian()) {
      out.write(reinterpret_cast<const char*>(data), std::streamsize(count * sizeof(T)));
    } else {
      std::vector<unsigned char> chunk;
      for (std::size_t i = 0; i < count; i += 65536) {
        const std::size_t n = std::min<std::size_t>(65536, count - i);
        chunk.resize(n * sizeof(T));
        for (std::size_t j = 0; j < n; ++j) {
          const T v =
              volfile::load_scalar<T>(reinterpret_cast<const unsigned char*>(data + i + j), true);
          std::memcpy(chunk.data() + j * sizeof(T), &v, sizeof(T));
        }
        out.write(reinterpret_cast<const char*>(chunk.data()), std::streamsize(chunk.size()));
      }
    }
    out.close();
    if (!out) throw Error(Status::io, "cannot write .npy (disk full?): '" + path + "'");
  });
}

}  // namespace

void save_npy(const std::string& path, const std::vector<std::size_t>& shape, const float* data) {
  save_npy_as(path, shape, data);
}

void save_npy(const std::string& path, const std::vector<std::size_t>& shape, const double* data) {
  save_npy_as(path, shape, data);
}

NpyArray load_npy(const std::string& path) {
  const volfile::TypedArray a = volfile::read_npy(path);
  NpyArray result;
  result.shape = a.shape;
  result.dtype = volfile::scalar_name(a.type);
  std::size_t count = 1;
  for (std::size_t n : a.shape) count *= n;  // read_npy checked it against the file size
  result.data.resize(count);
  volfile::for_each_value(a, count, [&](std::size_t i, double v) { result.data[i] = v; });
  return result;
}

}  // namespace ivr
