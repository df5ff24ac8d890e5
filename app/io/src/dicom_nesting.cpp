// How deep a DICOM file's sequences nest, found by walking its element headers without DCMTK
// (dicom_seg_internal.h: dicomNestingDepth). DCMTK 3.6.7 parses a sequence's items by
// recursion, with no limit: a file of sequences nested 100,000 deep (1.6 MB) overflows the
// stack. The walk keeps its own stack of open sequences and items, and skips values with a seek.
//
// Encoding (DICOM PS3.5 7.1, 7.5, A): a data element is tag (group, element), in explicit VR a
// two-letter VR, then a length of 4 bytes (2 for the explicit VRs outside kLongVrs); a length of
// 0xFFFFFFFF is undefined and ends at a delimiter. Items (FFFE,E000), item delimiters
// (FFFE,E00D) and sequence delimiters (FFFE,E0DD) are tag and 4-byte length in every transfer
// syntax. The file meta information (group 0002) is explicit VR little endian; the data set is
// in its Transfer Syntax UID's encoding (implicit VR little endian, explicit VR big endian, else
// explicit VR little endian). Deflated data sets are not walked (the depth is then unknown).
//
// What counts as a sequence errs towards DCMTK reading more of them, so the depth found is at
// least DCMTK's: an explicit SQ; any value of undefined length (DCMTK reads undefined-length UN
// as a sequence in implicit VR little endian, and undefined-length OB/OW as encapsulated pixel
// data, whose items are fragments, not nested); in implicit VR (no VR on the wire), a defined
// value that starts with an item tag.
#include <array>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "dicom_seg_internal.h"

namespace vh::io::detail {
namespace {

constexpr std::uint32_t kUndefined = 0xFFFFFFFFu;
constexpr std::uint16_t kItemGroup = 0xFFFE;
constexpr std::uint16_t kItem = 0xE000, kItemEnd = 0xE00D, kSequenceEnd = 0xE0DD;

/// The explicit VRs with a 2-byte length; every other one, unknown ones included, has a 4-byte
/// length (DCMTK assumes so for a VR it does not know, and reads it as UN).
bool isShortVr(const char* vr) {
  static const char* const kShortVrs[] = {"AE", "AS", "AT", "CS", "DA", "DS", "DT", "FL", "FD", "IS", "LO",
                                          "LT", "PN", "SH", "SL", "SS", "ST", "TM", "UI", "UL", "US"};
  for (const char* v : kShortVrs) {
    if (vr[0] == v[0] && vr[1] == v[1]) return true;
  }
  return false;
}

struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};

/// Sequential reads and seeks over the file; a short read means the file ends there.
class Reader {
 public:
  explicit Reader(const fs::path& path) : f_(std::fopen(path.c_str(), "rb")) {}
  bool open() const { return f_ != nullptr; }
  std::uint64_t pos() const { return pos_; }
  bool read(void* out, std::size_t n) {
    if (std::fread(out, 1, n, f_.get()) != n) return false;
    pos_ += n;
    return true;
  }
  bool seek(std::uint64_t to) {
    if (fseeko(f_.get(), static_cast<off_t>(to), SEEK_SET) != 0) return false;
    pos_ = to;
    return true;
  }

 private:
  std::unique_ptr<std::FILE, FileCloser> f_;
  std::uint64_t pos_ = 0;
};

struct Encoding {
  bool explicit_vr = true;
  bool big_endian = false;
};

std::uint16_t u16(const unsigned char* p, bool big) {
  return big ? static_cast<std::uint16_t>(p[0] << 8 | p[1]) : static_cast<std::uint16_t>(p[1] << 8 | p[0]);
}
std::uint32_t u32(const unsigned char* p, bool big) {
  return big ? std::uint32_t{p[0]} << 24 | std::uint32_t{p[1]} << 16 | std::uint32_t{p[2]} << 8 | p[3]
             : std::uint32_t{p[3]} << 24 | std::uint32_t{p[2]} << 16 | std::uint32_t{p[1]} << 8 | p[0];
}

/// An open sequence or item: where it ends (kUndefined: at its delimiter), the encoding of
/// what it holds, and for a sequence whether its items are pixel fragments (skipped whole).
struct Open {
  bool sequence = false;
  std::uint64_t end = kUndefined;
  Encoding encoding;
  bool fragments = false;
};

/// The walk: elements of the meta information and data set, items of sequences.
class Walk {
 public:
  Walk(Reader& in, std::size_t limit) : in_(in), limit_(limit) {}

  /// Walks from the reader's position with `encoding` until the end of the file, a value it
  /// cannot follow, group 0002 ending (meta_only) or a depth over the limit.
  void run(Encoding encoding, bool meta_only) {
    root_ = encoding;
    while (depth_ <= limit_) {
      while (!stack_.empty() && stack_.back().end != kUndefined && in_.pos() >= stack_.back().end) pop();
      const Encoding enc = stack_.empty() ? root_ : stack_.back().encoding;
      unsigned char head[8];
      if (!in_.read(head, 4)) return;
      const std::uint16_t group = u16(head, enc.big_endian), element = u16(head + 2, enc.big_endian);
      if (meta_only && stack_.empty() && group != 0x0002) {
        in_.seek(in_.pos() - 4);
        return;
      }
      if (group == kItemGroup) {
        if (!in_.read(head + 4, 4) || !delimiterOrItem(element, u32(head + 4, enc.big_endian))) return;
        continue;
      }
      if (!stack_.empty() && stack_.back().sequence) return;  // a sequence holds items only
      if (!dataElement(enc, group, element)) return;
    }
  }

  std::size_t depth() const { return max_depth_; }
  /// The transfer syntax of the meta information, when it was walked.
  const std::string& transferSyntax() const { return transfer_syntax_; }

 private:
  void push(Open o) {
    stack_.push_back(o);
    if (o.sequence) max_depth_ = std::max(max_depth_, ++depth_);
  }
  void pop() {
    if (stack_.back().sequence) --depth_;
    stack_.pop_back();
  }

  /// An item, item delimiter or sequence delimiter (tag and length read).
  bool delimiterOrItem(std::uint16_t element, std::uint32_t length) {
    const bool in_sequence = !stack_.empty() && stack_.back().sequence;
    if (element == kItem && in_sequence) {
      if (stack_.back().fragments) return length != kUndefined && in_.seek(in_.pos() + length);
      push({false, length == kUndefined ? kUndefined : in_.pos() + length, stack_.back().encoding, false});
      return true;
    }
    if (element == kItemEnd && !stack_.empty() && !stack_.back().sequence) {
      pop();
      return true;
    }
    if (element == kSequenceEnd && in_sequence) {
      pop();
      return true;
    }
    return false;  // out of place: DCMTK stops with an error here
  }

  /// A data element (tag read): its VR and length, then a sequence opened or its value skipped.
  bool dataElement(const Encoding& enc, std::uint16_t group, std::uint16_t element) {
    char vr[2] = {0, 0};
    std::uint32_t length = 0;
    unsigned char b[6];
    if (enc.explicit_vr) {
      if (!in_.read(vr, 2)) return false;
      if (isShortVr(vr)) {
        if (!in_.read(b, 2)) return false;
        length = u16(b, enc.big_endian);
      } else {
        if (!in_.read(b, 6)) return false;
        length = u32(b + 2, enc.big_endian);
      }
    } else {
      if (!in_.read(b, 4)) return false;
      length = u32(b, enc.big_endian);
    }
    const bool pixel_like = group == 0x7FE0 || (vr[0] == 'O' && (vr[1] == 'B' || vr[1] == 'W'));
    if (length == kUndefined) {
      // An SQ's items keep the data set's encoding; any other VR's (UN, unknown) are read by
      // DCMTK as implicit VR little endian.
      Encoding inner = enc;
      if (enc.explicit_vr && !(vr[0] == 'S' && vr[1] == 'Q')) inner = Encoding{false, false};
      push({true, kUndefined, inner, pixel_like});
      return true;
    }
    const std::uint64_t end = in_.pos() + length;
    const bool sequence = enc.explicit_vr ? vr[0] == 'S' && vr[1] == 'Q' : startsWithItem(length, enc);
    if (sequence) {
      push({true, end, enc, false});
      return true;
    }
    if (group == 0x0002 && element == 0x0010 && length < 256 && stack_.empty()) {
      std::string uid(length, '\0');
      if (!in_.read(uid.data(), length)) return false;
      while (!uid.empty() && (uid.back() == '\0' || uid.back() == ' ')) uid.pop_back();
      transfer_syntax_ = uid;
      return true;
    }
    return in_.seek(end);
  }

  /// Implicit VR: whether a value of `length` bytes starts with an item tag (read, then undone).
  bool startsWithItem(std::uint32_t length, const Encoding& enc) {
    if (length < 8) return false;
    unsigned char t[4];
    const std::uint64_t at = in_.pos();
    if (!in_.read(t, 4)) return false;
    in_.seek(at);
    return u16(t, enc.big_endian) == kItemGroup && u16(t + 2, enc.big_endian) == kItem;
  }

  Reader& in_;
  std::size_t limit_;
  Encoding root_;
  std::vector<Open> stack_;
  std::size_t depth_ = 0, max_depth_ = 0;
  std::string transfer_syntax_;
};

}  // namespace

std::size_t dicomNestingDepth(const fs::path& path, std::size_t limit) {
  Reader in(path);
  if (!in.open()) return 0;
  std::array<char, 132> head{};
  const bool preamble = in.read(head.data(), head.size()) && std::memcmp(head.data() + 128, "DICM", 4) == 0;
  if (!in.seek(preamble ? 132 : 0)) return 0;
  // The meta information (explicit VR little endian), when the file has one.
  Walk meta(in, limit);
  meta.run(Encoding{}, true);
  if (meta.depth() > limit) return meta.depth();
  const std::string& ts = meta.transferSyntax();
  if (ts == "1.2.840.10008.1.2.1.99") return meta.depth();  // deflated: not walked
  Encoding enc;
  if (ts == "1.2.840.10008.1.2") {
    enc.explicit_vr = false;
  } else if (ts == "1.2.840.10008.1.2.2") {
    enc.big_endian = true;
  } else if (ts.empty()) {
    // No meta information: DCMTK guesses; explicit VR when a VR's two upper-case letters follow
    // the first tag, else implicit.
    char probe[6];
    const std::uint64_t at = in.pos();
    enc.explicit_vr = in.read(probe, 6) && probe[4] >= 'A' && probe[4] <= 'Z' && probe[5] >= 'A' && probe[5] <= 'Z';
    in.seek(at);
  }
  Walk data(in, limit);
  data.run(enc, false);
  return std::max(meta.depth(), data.depth());
}

}  // namespace vh::io::detail
