// The JSON side of the native scene format (scene_json.cpp): a strict syntax
// check that runs before protobuf's parser, and the rewording of protobuf's
// own errors. Neither knows the schema; scene_proto.cpp converts the parsed
// message into the scene.
#pragma once

#include <string>
#include <string_view>

namespace locus {

// Empty when `text` is one well-formed JSON object (RFC 8259); else
// "<line>:<column>: <what is wrong>", or for a repeated key
// "<line>:<column>: <JSON path>: key \"<key>\" appears twice".
std::string json_syntax_error(std::string_view text);

// protobuf's JSON error turned into "<JSON path>: <what is wrong>"
// ("objects[0].sphere.radiuss: unknown field ...").
std::string rewrite_protobuf_error(std::string_view message);

}  // namespace locus
