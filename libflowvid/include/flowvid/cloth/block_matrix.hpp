#pragma once
// A square sparse matrix of 3x3 blocks (one block row per vertex) with a fixed
// pattern chosen once per mesh, plus a short list of extra blocks for contacts
// whose pairs change during a simulation. Assembly writes into precomputed
// slots, so the hot loop neither searches nor allocates.

#include <Eigen/Core>

#include <utility>
#include <vector>

namespace flowvid::cloth {

class BlockSparseMatrix {
public:
    BlockSparseMatrix() = default;
    // Pattern: every (i, j) in `pairs` and (j, i), plus the diagonal.
    BlockSparseMatrix(int block_rows, const std::vector<std::pair<int, int>>& pairs);

    int block_rows() const { return m_block_rows; }
    // Slot of block (i, j) in the fixed pattern, -1 if absent.
    int slot(int i, int j) const;
    Eigen::Matrix3d& block(int slot) { return m_blocks[static_cast<size_t>(slot)]; }
    const Eigen::Matrix3d& block(int slot) const { return m_blocks[static_cast<size_t>(slot)]; }
    int diagonal_slot(int i) const { return m_diagonal[static_cast<size_t>(i)]; }
    // Row i's slots are [row_begin(i), row_end(i)), sorted by column: those
    // before diagonal_slot(i) are left of the diagonal, those after it right.
    int row_begin(int i) const { return m_row_start[static_cast<size_t>(i)]; }
    int row_end(int i) const { return m_row_start[static_cast<size_t>(i) + 1]; }
    int column(int slot) const { return m_columns[static_cast<size_t>(slot)]; }

    // Adds to block (i, j): into the pattern when present, else to the extras.
    void add(int i, int j, const Eigen::Matrix3d& value);
    void set_zero();  // keeps the pattern, clears extras
    // this = scale * this + other_scale * other (same pattern; extras merged).
    void combine(double scale, const BlockSparseMatrix& other, double other_scale);
    void scale(double factor);

    // y = A x (x, y of size 3 * block_rows).
    void multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y) const;
    // Rows [begin, end) of A x from the fixed pattern only (no extras); y
    // must already have its size. For splitting a product between threads.
    void multiply_rows(const Eigen::VectorXd& x, Eigen::VectorXd& y, int begin, int end) const;
    // y += extras x.
    void add_extras_product(const Eigen::VectorXd& x, Eigen::VectorXd& y) const;
    Eigen::MatrixXd to_dense() const;

    // Calls f(row, col, block) for every stored block, extras included.
    template <class F>
    void for_each_block(F&& f) const {
        for (int i = 0; i < m_block_rows; ++i)
            for (int k = m_row_start[static_cast<size_t>(i)]; k < m_row_start[static_cast<size_t>(i) + 1]; ++k)
                f(i, m_columns[static_cast<size_t>(k)], m_blocks[static_cast<size_t>(k)]);
        for (const Extra& e : m_extras) f(e.row, e.col, e.value);
    }

    // Blocks outside the fixed pattern (contact pairs), summed by multiply().
    struct Extra {
        int row;
        int col;
        Eigen::Matrix3d value;
    };
    const std::vector<Extra>& extras() const { return m_extras; }

private:
    int m_block_rows = 0;
    std::vector<int> m_row_start;
    std::vector<int> m_columns;
    std::vector<int> m_diagonal;
    std::vector<Eigen::Matrix3d> m_blocks;
    std::vector<Extra> m_extras;
};

}  // namespace flowvid::cloth
