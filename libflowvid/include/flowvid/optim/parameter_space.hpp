#pragma once
// The box the optimizer searches: named parameters with bounds, each searched
// linearly or in log space (stiffness and damping span decades: the thesis's
// tables run from 1e-7 to 4000). Optimizers work in the unit cube
// u in [0, 1]^n; value = lower + u (upper - lower), or
// lower (upper / lower)^u in log space.

#include <Eigen/Core>

#include <string>
#include <vector>

namespace flowvid::optim {

struct Parameter {
    std::string name;
    double lower = 0.0;
    double upper = 1.0;
    bool log_scale = false;  // needs 0 < lower
};

class ParameterSpace {
public:
    ParameterSpace() = default;
    // Throws std::invalid_argument listing every bad parameter (lower >= upper,
    // non-finite bounds, log scale with lower <= 0, empty or repeated names).
    explicit ParameterSpace(std::vector<Parameter> parameters);

    int size() const { return static_cast<int>(m_parameters.size()); }
    const Parameter& operator[](int i) const { return m_parameters[static_cast<std::size_t>(i)]; }
    const std::vector<Parameter>& parameters() const { return m_parameters; }
    // Index of a parameter by name, -1 when absent.
    int index_of(const std::string& name) const;

    Eigen::VectorXd to_values(const Eigen::VectorXd& unit) const;
    // Values outside the bounds map outside [0, 1].
    Eigen::VectorXd to_unit(const Eigen::VectorXd& values) const;
    static bool inside_unit_cube(const Eigen::VectorXd& unit);
    Eigen::VectorXd clamp_values(const Eigen::VectorXd& values) const;

private:
    std::vector<Parameter> m_parameters;
};

}  // namespace flowvid::optim
