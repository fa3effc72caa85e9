#include "flowvid/cloth/block_matrix.hpp"

#include <algorithm>

namespace flowvid::cloth {

BlockSparseMatrix::BlockSparseMatrix(int block_rows, const std::vector<std::pair<int, int>>& pairs)
    : m_block_rows(block_rows) {
    std::vector<std::vector<int>> rows(static_cast<size_t>(block_rows));
    for (int i = 0; i < block_rows; ++i) rows[static_cast<size_t>(i)].push_back(i);
    for (const auto& [i, j] : pairs) {
        rows[static_cast<size_t>(i)].push_back(j);
        rows[static_cast<size_t>(j)].push_back(i);
    }
    m_row_start.assign(static_cast<size_t>(block_rows) + 1, 0);
    for (int i = 0; i < block_rows; ++i) {
        auto& r = rows[static_cast<size_t>(i)];
        std::sort(r.begin(), r.end());
        r.erase(std::unique(r.begin(), r.end()), r.end());
        m_row_start[static_cast<size_t>(i) + 1] = m_row_start[static_cast<size_t>(i)] + static_cast<int>(r.size());
        m_columns.insert(m_columns.end(), r.begin(), r.end());
    }
    m_blocks.assign(m_columns.size(), Eigen::Matrix3d::Zero());
    m_diagonal.resize(static_cast<size_t>(block_rows));
    for (int i = 0; i < block_rows; ++i) m_diagonal[static_cast<size_t>(i)] = slot(i, i);
}

int BlockSparseMatrix::slot(int i, int j) const {
    if (i < 0 || i >= m_block_rows) return -1;
    const auto begin = m_columns.begin() + m_row_start[static_cast<size_t>(i)];
    const auto end = m_columns.begin() + m_row_start[static_cast<size_t>(i) + 1];
    const auto it = std::lower_bound(begin, end, j);
    if (it == end || *it != j) return -1;
    return static_cast<int>(it - m_columns.begin());
}

void BlockSparseMatrix::add(int i, int j, const Eigen::Matrix3d& value) {
    const int s = slot(i, j);
    if (s >= 0)
        m_blocks[static_cast<size_t>(s)] += value;
    else
        m_extras.push_back({i, j, value});
}

void BlockSparseMatrix::set_zero() {
    for (Eigen::Matrix3d& b : m_blocks) b.setZero();
    m_extras.clear();
}

void BlockSparseMatrix::combine(double scale, const BlockSparseMatrix& other, double other_scale) {
    for (size_t k = 0; k < m_blocks.size(); ++k) m_blocks[k] = scale * m_blocks[k] + other_scale * other.m_blocks[k];
    for (Extra& e : m_extras) e.value *= scale;
    for (const Extra& e : other.m_extras) m_extras.push_back({e.row, e.col, other_scale * e.value});
}

void BlockSparseMatrix::scale(double factor) {
    for (Eigen::Matrix3d& b : m_blocks) b *= factor;
    for (Extra& e : m_extras) e.value *= factor;
}

void BlockSparseMatrix::multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y) const {
    y.resize(3 * m_block_rows);
    multiply_rows(x, y, 0, m_block_rows);
    add_extras_product(x, y);
}

void BlockSparseMatrix::multiply_rows(const Eigen::VectorXd& x, Eigen::VectorXd& y, int begin, int end) const {
    const double* xp = x.data();
    double* yp = y.data();
    const int* columns = m_columns.data();
    const Eigen::Matrix3d* blocks = m_blocks.data();
    for (int i = begin; i < end; ++i) {
        double s0 = 0.0, s1 = 0.0, s2 = 0.0;
        const int row_end = m_row_start[static_cast<size_t>(i) + 1];
        for (int k = m_row_start[static_cast<size_t>(i)]; k < row_end; ++k) {
            const double* b = blocks[k].data();  // column-major
            const double* xj = xp + 3 * columns[k];
            s0 += b[0] * xj[0] + b[3] * xj[1] + b[6] * xj[2];
            s1 += b[1] * xj[0] + b[4] * xj[1] + b[7] * xj[2];
            s2 += b[2] * xj[0] + b[5] * xj[1] + b[8] * xj[2];
        }
        yp[3 * i] = s0;
        yp[3 * i + 1] = s1;
        yp[3 * i + 2] = s2;
    }
}

void BlockSparseMatrix::add_extras_product(const Eigen::VectorXd& x, Eigen::VectorXd& y) const {
    for (const Extra& e : m_extras) y.segment<3>(3 * e.row).noalias() += e.value * x.segment<3>(3 * e.col);
}

Eigen::MatrixXd BlockSparseMatrix::to_dense() const {
    Eigen::MatrixXd dense = Eigen::MatrixXd::Zero(3 * m_block_rows, 3 * m_block_rows);
    for (int i = 0; i < m_block_rows; ++i)
        for (int k = m_row_start[static_cast<size_t>(i)]; k < m_row_start[static_cast<size_t>(i) + 1]; ++k)
            dense.block<3, 3>(3 * i, 3 * m_columns[static_cast<size_t>(k)]) += m_blocks[static_cast<size_t>(k)];
    for (const Extra& e : m_extras) dense.block<3, 3>(3 * e.row, 3 * e.col) += e.value;
    return dense;
}

}  // namespace flowvid::cloth
