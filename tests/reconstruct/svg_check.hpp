// svg_check.hpp — a strict small XML reader for the tests of written SVG files.
#pragma once
#include <cctype>
#include <cmath>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

namespace ivr::test {

struct XmlElement {
  std::string name;
  std::map<std::string, std::string> attributes;  // entity references decoded
  std::string text;                               // its own character data, decoded
};

// Every element of `xml` in document order. Throws std::runtime_error naming the first breach of
// well-formedness it finds: an unclosed or mismatched tag, an unquoted or repeated attribute, a
// raw '<' or an unknown entity in text or attributes, a second root or text after the root. (No
// DTDs, CDATA or processing instructions beyond the leading declaration: ivr writes none.)
inline std::vector<XmlElement> parse_xml(const std::string& xml) {
  std::size_t i = 0;
  const auto fail = [&](const std::string& why) {
    throw std::runtime_error("XML: " + why + " at offset " + std::to_string(i));
  };
  const auto decode = [&](const std::string& s) {
    std::string out;
    for (std::size_t k = 0; k < s.size(); ++k) {
      if (s[k] == '<') fail("raw '<' in text");
      if (s[k] != '&') {
        out += s[k];
        continue;
      }
      const std::size_t end = s.find(';', k);
      if (end == std::string::npos) fail("unterminated entity");
      const std::string e = s.substr(k + 1, end - k - 1);
      static const std::map<std::string, std::string> named = {
          {"amp", "&"}, {"lt", "<"}, {"gt", ">"}, {"quot", "\""}, {"apos", "'"}};
      if (named.count(e)) {
        out += named.at(e);
      } else if (e.size() > 1 && e[0] == '#') {
        out += '?';  // a character reference: valid, its character not needed by the tests
      } else {
        fail("unknown entity '&" + e + ";'");
      }
      k = end;
    }
    return out;
  };
  const auto is_name = [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' || c == ':' ||
           c == '.';
  };
  const auto skip_space = [&] {
    while (i < xml.size() && std::isspace(static_cast<unsigned char>(xml[i]))) ++i;
  };

  if (xml.rfind("<?xml", 0) == 0) {
    i = xml.find("?>");
    if (i == std::string::npos) fail("unterminated declaration");
    i += 2;
  }
  std::vector<XmlElement> elements;
  std::vector<std::size_t> open;  // indices into `elements`
  bool root_done = false;
  while (i < xml.size()) {
    if (xml[i] != '<') {
      const std::size_t end = std::min(xml.find('<', i), xml.size());
      const std::string text = decode(xml.substr(i, end - i));
      if (open.empty()) {
        for (char c : text)
          if (!std::isspace(static_cast<unsigned char>(c))) fail("text outside the root");
      } else {
        elements[open.back()].text += text;
      }
      i = end;
      continue;
    }
    if (xml.compare(i, 4, "<!--") == 0) {
      i = xml.find("-->", i);
      if (i == std::string::npos) fail("unterminated comment");
      i += 3;
      continue;
    }
    if (xml.compare(i, 2, "</") == 0) {
      i += 2;
      const std::size_t start = i;
      while (i < xml.size() && is_name(xml[i])) ++i;
      const std::string name = xml.substr(start, i - start);
      skip_space();
      if (i >= xml.size() || xml[i] != '>') fail("bad closing tag");
      if (open.empty() || elements[open.back()].name != name) fail("mismatched </" + name + ">");
      open.pop_back();
      root_done = open.empty();
      ++i;
      continue;
    }
    ++i;
    if (root_done) fail("a second root element");
    XmlElement e;
    const std::size_t start = i;
    while (i < xml.size() && is_name(xml[i])) ++i;
    e.name = xml.substr(start, i - start);
    if (e.name.empty()) fail("empty tag name");
    bool closed = false;
    for (;;) {
      const std::size_t before = i;
      skip_space();
      if (i >= xml.size()) fail("unterminated tag <" + e.name + ">");
      if (xml.compare(i, 2, "/>") == 0) {
        closed = true;
        i += 2;
        break;
      }
      if (xml[i] == '>') {
        ++i;
        break;
      }
      if (i == before) fail("no space before an attribute");
      const std::size_t a = i;
      while (i < xml.size() && is_name(xml[i])) ++i;
      const std::string name = xml.substr(a, i - a);
      if (name.empty() || i + 1 >= xml.size() || xml[i] != '=' ||
          (xml[i + 1] != '"' && xml[i + 1] != '\''))
        fail("bad attribute in <" + e.name + ">");
      const char quote = xml[i + 1];
      const std::size_t end = xml.find(quote, i + 2);
      if (end == std::string::npos) fail("unterminated attribute value");
      if (e.attributes.count(name)) fail("repeated attribute " + name);
      e.attributes[name] = decode(xml.substr(i + 2, end - i - 2));
      i = end + 1;
    }
    elements.push_back(e);
    if (closed)
      root_done = open.empty();
    else
      open.push_back(elements.size() - 1);
  }
  if (!open.empty()) fail("<" + elements[open.back()].name + "> is never closed");
  if (elements.empty()) fail("no root element");
  return elements;
}

// A tick label of the loss plot read back: "10⁻³" -> 1e-3, "2×10⁻³" -> 2e-3; NaN if it is not one.
inline double tick_value(const std::string& s) {
  static const std::vector<std::pair<std::string, char>> sup = {
      {"⁰", '0'}, {"¹", '1'}, {"²", '2'}, {"³", '3'}, {"⁴", '4'}, {"⁵", '5'},
      {"⁶", '6'}, {"⁷", '7'}, {"⁸", '8'}, {"⁹", '9'}, {"⁻", '-'}};
  std::size_t i = 0;
  double m = 1;
  const std::size_t times = s.find("×");
  if (times != std::string::npos) {
    try {
      m = std::stod(s.substr(0, times));
    } catch (const std::exception&) {
      return NAN;
    }
    i = times + std::string("×").size();
  }
  if (s.compare(i, 2, "10") != 0) return NAN;
  i += 2;
  std::string exponent;
  while (i < s.size()) {
    bool found = false;
    for (const auto& [glyph, c] : sup)
      if (s.compare(i, glyph.size(), glyph) == 0) {
        exponent += c;
        i += glyph.size();
        found = true;
        break;
      }
    if (!found) return NAN;
  }
  if (exponent.empty() || exponent == "-") return NAN;
  return m * std::pow(10.0, std::stoi(exponent));
}

}  // namespace ivr::test
