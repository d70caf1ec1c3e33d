#pragma once
// Files of the `cairn segment` contract (docs/file-formats.md): segments.json, labels.txt,
// segments.ply.
#include <filesystem>
#include <nlohmann/json.hpp>

#include "cairn/segmentation/segmenter.hpp"

namespace cairn {

/// segments.json content. Coordinates in the world frame (cloud.origin added).
[[nodiscard]] nlohmann::json segments_json(const PointCloud& cloud, const SegmentationResult& result);

/// Writes DIR/segments.json, DIR/labels.txt (one label per input point: `input_labels`, which
/// may be longer than the cloud when invalid input points were dropped) and DIR/segments.ply
/// (the cloud coloured by segment, with a `label` property).
void write_segmentation(const std::filesystem::path& dir, const PointCloud& cloud,
                        const SegmentationResult& result, const std::vector<std::int32_t>& input_labels);

/// A distinct colour per segment id; ground grey, no-object dark.
[[nodiscard]] Rgb label_color(std::int32_t label);

}  // namespace cairn
