#pragma once
// JSON arrays of Eigen vectors and matrices, as capture.json writes them
// (capture.cpp) and reads them back into messages (capture_read.cpp). Not
// part of the public interface.

#include <Eigen/Core>
#include <nlohmann/json.hpp>

namespace flowvid::formats::capture_json {

inline nlohmann::json vector_json(const Eigen::VectorXd& v) {
    nlohmann::json list = nlohmann::json::array();
    for (Eigen::Index i = 0; i < v.size(); ++i) list.push_back(v[i]);
    return list;
}

inline nlohmann::json matrix_json(const Eigen::MatrixXd& m) {
    nlohmann::json rows = nlohmann::json::array();
    for (Eigen::Index r = 0; r < m.rows(); ++r) rows.push_back(vector_json(m.row(r).transpose()));
    return rows;
}

}  // namespace flowvid::formats::capture_json
