// The first pass over a scene's JSON text: it checks the whole text (syntax, number range, nesting, size of each
// part) and builds a JSON value of everything except the entries of the long lists (objects, materials,
// textures), of which it keeps only where their text lies, so that the memory a scene costs while it is read
// stays near the size of its text.
#pragma once

#include <cstddef>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

namespace pt {

// Each list entry (an object, a material, a texture), and the rest of the file, may hold at most this many JSON
// values: a scene's entries hold a few dozen, and the limit bounds the memory of the one entry read at a time.
inline constexpr std::size_t kMaxJsonValuesPerEntry = 100000;

struct TextRange {
  std::size_t begin = 0, end = 0;  // offsets into the text, end one past the last character
};

struct JsonOutline {
  // The document; where /objects is an array, or /materials or /textures an object, it holds that list empty,
  // and its entries are listed below.
  nlohmann::json root;
  std::optional<std::vector<TextRange>> objects;                        // the elements of /objects, in order
  std::optional<std::map<std::string, TextRange>> materials, textures;  // by key; a key given twice keeps its last
};

// Throws InputError ("SOURCE:LINE:COLUMN: ...") for text that is not JSON, a number beyond a double's range,
// nesting deeper than kMaxJsonNesting, or a part with more than kMaxJsonValuesPerEntry values. `passed`, where
// given, hears at each list entry that the text before it will be read again only for a message.
JsonOutline read_json_outline(std::string_view text, const std::string& source, const std::function<void(std::size_t)>& passed = {});

}  // namespace pt
