// gzip.cpp — gzip inflation (zlib) with size limits and one-line errors naming the file.
#include "io/gzip.hpp"

#include <zlib.h>

#include <algorithm>

#include "ivr/error.hpp"

namespace ivr::volfile {

namespace {

[[noreturn]] void fail(const std::string& path, const std::string& what) {
  throw Error(Status::io, what + ": '" + path + "'");
}

// Inflates up to `want` bytes. With `head`, stops as soon as it has them and returns fewer when the
// stream ends sooner; otherwise inflates to the end of the completing member and demands `want`.
std::vector<unsigned char> inflate_gzip(const unsigned char* data, std::size_t size,
                                        std::size_t want, bool head, const std::string& path,
                                        const std::string& kind) {
  z_stream zs{};
  if (inflateInit2(&zs, 16 + MAX_WBITS) != Z_OK) fail(path, "cannot initialise zlib to read");
  struct End {
    z_stream* z;
    ~End() { inflateEnd(z); }
  } end{&zs};
  std::vector<unsigned char> out(std::min(want, std::max<std::size_t>(1 << 20, size * 4)));
  unsigned char spill[16384];
  std::size_t in_done = 0, produced = 0;
  constexpr std::size_t kChunk = std::size_t(1) << 30;  // z_stream counts are 32-bit
  while (true) {
    if (produced == out.size() && out.size() < want) out.resize(std::min(want, out.size() * 2));
    const bool full = produced == want;
    if (full && head) break;
    zs.next_in = const_cast<Bytef*>(data + in_done);
    zs.avail_in = uInt(std::min(size - in_done, kChunk));
    zs.next_out = full ? spill : out.data() + produced;
    zs.avail_out = uInt(full ? sizeof(spill) : std::min(out.size() - produced, kChunk));
    const uInt in_before = zs.avail_in, out_before = zs.avail_out;
    const int ret = inflate(&zs, Z_NO_FLUSH);
    in_done += in_before - zs.avail_in;
    if (!full) produced += out_before - zs.avail_out;
    if (ret == Z_STREAM_END) {
      if (produced == want || in_done == size) break;
      inflateReset(&zs);  // another gzip member follows
    } else if (ret == Z_BUF_ERROR && in_done == size) {
      if (head) break;
      fail(path, "truncated gzip data in " + kind + " (the stream ends after " +
                     std::to_string(produced) + " of the " + std::to_string(want) +
                     " bytes the header needs)");
    } else if (ret != Z_OK) {
      const std::string why = zs.msg ? zs.msg : "zlib error " + std::to_string(ret);
      fail(path, "corrupted gzip data in " + kind + " (" + why + ")");
    }
  }
  if (head) {
    out.resize(produced);
  } else if (produced < want) {
    fail(path, "truncated gzip data in " + kind + " (it inflates to " + std::to_string(produced) +
                   " bytes but the header needs " + std::to_string(want) + ")");
  }
  return out;
}

}  // namespace

bool is_gzip(const unsigned char* data, std::size_t size) {
  return size >= 2 && data[0] == 0x1f && data[1] == 0x8b;
}

std::vector<unsigned char> gunzip(const unsigned char* data, std::size_t size, std::size_t want,
                                  const std::string& path, const std::string& kind) {
  return inflate_gzip(data, size, want, false, path, kind);
}

std::vector<unsigned char> gunzip_head(const unsigned char* data, std::size_t size, std::size_t max,
                                       const std::string& path, const std::string& kind) {
  return inflate_gzip(data, size, max, true, path, kind);
}

}  // namespace ivr::volfile
