// nrrd.cpp — NRRD volumes: header parsing, detached data files, raw/gzip/ascii encodings.
#include "io/nrrd.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <limits>
#include <map>
#include <sstream>
#include <type_traits>

#include "io/files.hpp"
#include "io/gzip.hpp"
#include "ivr/error.hpp"

namespace ivr::volfile {

namespace {

[[noreturn]] void fail(const std::string& path, const std::string& what) {
  throw Error(Status::io, what + ": '" + path + "'");
}

std::string trim(const std::string& s) {
  std::size_t b = 0, e = s.size();
  while (b < e && std::isspace(static_cast<unsigned char>(s[b]))) ++b;
  while (e > b && std::isspace(static_cast<unsigned char>(s[e - 1]))) --e;
  return s.substr(b, e - b);
}

std::string lower(std::string s) {
  for (char& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

std::vector<std::string> split_blanks(const std::string& s) {
  std::istringstream in(s);
  std::vector<std::string> tokens;
  for (std::string t; in >> t;) tokens.push_back(t);
  return tokens;
}

// Whole-token integer parse; false on junk, overflow or a value below `min`.
bool parse_int(const std::string& text, long long min, long long* value) {
  const std::string t = trim(text);
  if (t.empty()) return false;
  char* end = nullptr;
  errno = 0;
  const long long v = std::strtoll(t.c_str(), &end, 10);
  if (errno != 0 || *end != '\0' || v < min) return false;
  *value = v;
  return true;
}

// Whole-token floating-point parse ("nan" allowed: NRRD uses it for "unknown").
bool parse_double(const std::string& text, double* value) {
  const std::string t = trim(text);
  if (t.empty()) return false;
  char* end = nullptr;
  *value = std::strtod(t.c_str(), &end);
  return *end == '\0';
}

// Per-axis spacing from "spacings" (numbers or nan) or "space directions" (vectors or none);
// nullopt for an axis that states none.
std::vector<std::optional<double>> axis_spacings(const std::map<std::string, std::string>& fields,
                                                 std::size_t dimension, const std::string& path) {
  std::vector<std::optional<double>> result(dimension);
  if (auto it = fields.find("space directions"); it != fields.end()) {
    // Tokens are "(a,b,c)" or "none"; blanks may appear inside the parentheses.
    std::vector<std::string> tokens;
    const std::string& v = it->second;
    for (std::size_t i = 0; i < v.size();) {
      if (std::isspace(static_cast<unsigned char>(v[i]))) {
        ++i;
      } else if (v[i] == '(') {
        const std::size_t close = v.find(')', i);
        if (close == std::string::npos)
          fail(path, "malformed NRRD 'space directions' (missing ')')");
        tokens.push_back(v.substr(i, close - i + 1));
        i = close + 1;
      } else {
        std::size_t j = i;
        while (j < v.size() && !std::isspace(static_cast<unsigned char>(v[j]))) ++j;
        tokens.push_back(v.substr(i, j - i));
        i = j;
      }
    }
    if (tokens.size() != dimension)
      fail(path, "NRRD 'space directions' has " + std::to_string(tokens.size()) +
                     " entries but dimension is " + std::to_string(dimension));
    for (std::size_t a = 0; a < dimension; ++a) {
      if (lower(tokens[a]) == "none") continue;
      if (tokens[a].front() != '(')
        fail(path, "malformed NRRD 'space directions' entry '" + tokens[a] + "'");
      std::string inner = tokens[a].substr(1, tokens[a].size() - 2);
      std::replace(inner.begin(), inner.end(), ',', ' ');
      double sum = 0;
      std::size_t n = 0;
      for (const std::string& c : split_blanks(inner)) {
        double x;
        if (!parse_double(c, &x))
          fail(path, "malformed NRRD 'space directions' entry '" + tokens[a] + "'");
        sum += x * x;
        ++n;
      }
      if (n == 0) fail(path, "malformed NRRD 'space directions' entry '" + tokens[a] + "'");
      if (std::isfinite(sum)) result[a] = std::sqrt(sum);
    }
  } else if (auto it2 = fields.find("spacings"); it2 != fields.end()) {
    const std::vector<std::string> tokens = split_blanks(it2->second);
    if (tokens.size() != dimension)
      fail(path, "NRRD 'spacings' has " + std::to_string(tokens.size()) +
                     " entries but dimension is " + std::to_string(dimension));
    for (std::size_t a = 0; a < dimension; ++a) {
      double x;
      if (!parse_double(tokens[a], &x)) fail(path, "malformed NRRD spacing '" + tokens[a] + "'");
      if (std::isfinite(x)) result[a] = std::fabs(x);  // the sign only states a direction
    }
  }
  for (const auto& s : result)
    if (s && *s == 0) fail(path, "NRRD states a zero spacing");
  return result;
}

// Parses whitespace (or comma) separated numbers into `count` elements of `type`, host order.
std::vector<unsigned char> parse_ascii(const unsigned char* data, std::size_t size,
                                       std::size_t count, ScalarType type,
                                       const std::string& path) {
  const std::size_t elem = scalar_size(type);
  // n values need at least 2n - 1 characters, so this bound holds every value the text can have.
  std::vector<unsigned char> out(std::min(count, size / 2 + 1) * elem);
  std::string text(reinterpret_cast<const char*>(data), size);
  std::replace(text.begin(), text.end(), ',', ' ');
  const char* p = text.c_str();
  const char* const end = p + text.size();
  std::size_t n = 0;
  for (; n < count; ++n) {
    while (p < end && std::isspace(static_cast<unsigned char>(*p))) ++p;
    if (p == end) break;
    char* stop = nullptr;
    const double v = std::strtod(p, &stop);
    if (stop == p) {
      const char* tok_end = p;
      while (tok_end < end && !std::isspace(static_cast<unsigned char>(*tok_end))) ++tok_end;
      fail(path, "malformed ascii NRRD value '" + std::string(p, tok_end) + "' (value " +
                     std::to_string(n) + ")");
    }
    p = stop;
    unsigned char* dst = out.data() + n * elem;
    auto store = [&](auto typed) {
      using T = decltype(typed);
      if constexpr (std::is_integral_v<T>) {
        if (!(v >= double(std::numeric_limits<T>::min()) &&
              v <= double(std::numeric_limits<T>::max())))
          fail(path,
               "ascii NRRD value " + std::to_string(v) + " does not fit " + scalar_name(type));
      }
      const T t = static_cast<T>(v);
      std::memcpy(dst, &t, sizeof(T));
    };
    switch (type) {
      case ScalarType::uint8:
        store(std::uint8_t{});
        break;
      case ScalarType::int8:
        store(std::int8_t{});
        break;
      case ScalarType::uint16:
        store(std::uint16_t{});
        break;
      case ScalarType::int16:
        store(std::int16_t{});
        break;
      case ScalarType::uint32:
        store(std::uint32_t{});
        break;
      case ScalarType::int32:
        store(std::int32_t{});
        break;
      case ScalarType::float32:
        store(float{});
        break;
      case ScalarType::float64:
        store(double{});
        break;
    }
  }
  if (n < count)
    fail(path, "truncated ascii NRRD data (" + std::to_string(n) + " values but sizes need " +
                   std::to_string(count) + ")");
  return out;
}

}  // namespace

TypedArray read_nrrd(const std::string& path) {
  TypedArray a;
  std::vector<unsigned char> file = read_binary_file(path, "NRRD file");
  std::size_t pos = 0;
  // Next line without its "\n" or "\r\n"; false at the end of the file.
  auto next_line = [&](std::string* line) {
    if (pos >= file.size()) return false;
    const auto begin = file.begin() + std::ptrdiff_t(pos);
    const auto nl = std::find(begin, file.end(), '\n');
    line->assign(begin, nl);
    if (!line->empty() && line->back() == '\r') line->pop_back();
    pos = nl == file.end() ? file.size() : std::size_t(nl - file.begin()) + 1;
    return true;
  };

  std::string line;
  if (file.size() < 8 || std::memcmp(file.data(), "NRRD000", 7) != 0 || file[7] < '1' ||
      file[7] > '5')
    fail(path, "not a NRRD file (bad magic, expected NRRD0001..NRRD0005)");
  next_line(&line);

  std::map<std::string, std::string> fields;
  bool blank_line = false;
  int line_no = 1;
  while (next_line(&line)) {
    ++line_no;
    if (line.empty()) {
      blank_line = true;  // attached data starts right after it
      break;
    }
    if (line[0] == '#' || line.find(":=") != std::string::npos) continue;  // comment, key/value
    const std::size_t colon = line.find(": ");
    if (colon == std::string::npos)
      fail(path, "malformed NRRD header line " + std::to_string(line_no) + " '" + line +
                     "' (expected 'field: value')");
    std::string key = lower(trim(line.substr(0, colon)));
    // "datafile", "byteskip", "lineskip" are older spellings of the spaced names.
    if (key == "datafile") key = "data file";
    if (key == "byteskip") key = "byte skip";
    if (key == "lineskip") key = "line skip";
    if (!fields.emplace(key, trim(line.substr(colon + 2))).second)
      fail(path, "NRRD field '" + key + "' appears twice");
  }
  for (const char* required : {"type", "dimension", "sizes", "encoding"})
    if (!fields.count(required))
      fail(path, std::string("NRRD header lacks the '") + required + "' field");

  const std::optional<ScalarType> type = parse_scalar_type(fields["type"]);
  if (!type)
    fail(path, "unsupported NRRD type '" + fields["type"] +
                   "' (supported: 8-, 16- and 32-bit integers, float, double)");
  a.type = *type;

  long long dimension = 0;
  if (!parse_int(fields["dimension"], 1, &dimension))
    fail(path, "malformed NRRD dimension '" + fields["dimension"] + "'");
  const std::vector<std::string> size_tokens = split_blanks(fields["sizes"]);
  if (size_tokens.size() != std::size_t(dimension))
    fail(path, "NRRD 'sizes' has " + std::to_string(size_tokens.size()) +
                   " entries but dimension is " + std::to_string(dimension));
  std::vector<std::size_t> sizes;  // fastest axis first
  for (const std::string& t : size_tokens) {
    long long n = 0;
    if (!parse_int(t, 1, &n)) fail(path, "malformed NRRD size '" + t + "' (sizes must be >= 1)");
    sizes.push_back(std::size_t(n));
  }
  std::vector<std::optional<double>> spacings = axis_spacings(fields, sizes.size(), path);
  if (dimension == 4 && sizes[0] == 1) {  // e.g. a one-component vector axis first
    sizes.erase(sizes.begin());
    spacings.erase(spacings.begin());
  } else if (dimension != 3) {
    throw Error(Status::invalid_argument,
                "NRRD volume must be 3-D (or 4-D with a first axis of size 1) but has dimension " +
                    std::to_string(dimension) + " and sizes " + fields["sizes"] + ": '" + path +
                    "'");
  }
  a.shape = {sizes[2], sizes[1], sizes[0]};
  if (spacings[0] || spacings[1] || spacings[2])
    a.spacing =
        glm::dvec3(spacings[0].value_or(1.0), spacings[1].value_or(1.0), spacings[2].value_or(1.0));
  const std::size_t count = checked_count(a.shape, kMaxVoxels, path);
  const std::size_t need = count * scalar_size(a.type);

  if (auto it = fields.find("endian"); it != fields.end()) {
    const std::string e = lower(it->second);
    if (e != "little" && e != "big") fail(path, "malformed NRRD endian '" + it->second + "'");
    a.big_endian = e == "big";
  }
  const std::string encoding = lower(fields["encoding"]);
  enum { raw, gzip, ascii } enc;
  if (encoding == "raw") {
    enc = raw;
  } else if (encoding == "gzip" || encoding == "gz") {
    enc = gzip;
  } else if (encoding == "ascii" || encoding == "text" || encoding == "txt") {
    enc = ascii;
  } else if (encoding == "bzip2" || encoding == "bz2" || encoding == "hex" || encoding == "zrl") {
    fail(path,
         "NRRD encoding '" + fields["encoding"] + "' is not supported (raw, gzip, ascii are)");
  } else {
    fail(path, "unknown NRRD encoding '" + fields["encoding"] + "'");
  }
  long long line_skip = 0, byte_skip = 0;
  if (fields.count("line skip") && !parse_int(fields["line skip"], 0, &line_skip))
    fail(path, "malformed NRRD line skip '" + fields["line skip"] + "'");
  if (fields.count("byte skip") && !parse_int(fields["byte skip"], -1, &byte_skip))
    fail(path, "malformed NRRD byte skip '" + fields["byte skip"] + "'");
  if (byte_skip == -1 && enc != raw) fail(path, "NRRD byte skip -1 only works with raw encoding");
  if (byte_skip != 0 && enc == ascii) fail(path, "NRRD byte skip does not apply to ascii encoding");

  // The data: the rest of this file, or a detached file named relative to this header's folder.
  std::string data_path = path;
  if (auto it = fields.find("data file"); it != fields.end()) {
    const std::string& name = it->second;
    if (name.rfind("LIST", 0) == 0 || name.find('%') != std::string::npos)
      fail(path, "multi-file NRRD data ('data file: " + name + "') is not supported");
    std::filesystem::path p(name);
    if (p.is_relative()) p = std::filesystem::path(parent_dir(path)) / p;
    data_path = p.string();
    file = read_binary_file(data_path, "NRRD data file");
    pos = 0;
  } else if (!blank_line) {
    fail(path, "NRRD header has no data (no blank line before attached data, no 'data file')");
  }
  for (long long i = 0; i < line_skip; ++i) {
    const auto nl = std::find(file.begin() + std::ptrdiff_t(pos), file.end(), '\n');
    if (nl == file.end()) fail(data_path, "NRRD line skip runs past the end of the data");
    pos = std::size_t(nl - file.begin()) + 1;
  }
  const std::string sizes_text = "sizes " + fields["sizes"] + " of " + scalar_name(a.type);
  if (enc == raw) {
    const std::size_t avail = file.size() - pos;
    if (byte_skip == -1) {  // the data is the last `need` bytes
      if (need > avail) fail(data_path, "truncated NRRD raw data");
      pos = file.size() - need;
    } else if (std::size_t(byte_skip) > avail) {
      fail(data_path, "NRRD byte skip runs past the end of the data");
    } else {
      pos += std::size_t(byte_skip);
    }
    if (file.size() - pos < need)
      fail(data_path, "truncated NRRD raw data (" + std::to_string(file.size() - pos) +
                          " bytes but " + sizes_text + " need " + std::to_string(need) + ")");
    a.bytes = std::move(file);
    a.offset = pos;
  } else if (enc == gzip) {
    a.bytes = gunzip(file.data() + pos, file.size() - pos, std::size_t(byte_skip) + need, data_path,
                     "NRRD");
    a.offset = std::size_t(byte_skip);
  } else {
    a.bytes = parse_ascii(file.data() + pos, file.size() - pos, count, a.type, data_path);
    a.big_endian = host_is_big_endian();
  }
  return a;
}

}  // namespace ivr::volfile
