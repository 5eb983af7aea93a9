#pragma once
// Arithmetic expressions as OpenSim writes them in a model (Lepton's grammar, which
// ExpressionBasedCoordinateForce uses): numbers, named variables, + - * / ^ (right-associative,
// binding tighter than unary minus), parentheses, Lepton's functions (sqrt exp log sin cos sec csc tan
// cot asin acos atan sinh cosh tanh erf erfc step delta square cube recip min max abs) and
// subexpressions after semicolons ("a*x; a=2").
#include <stdexcept>
#include <string>
#include <vector>

namespace cpgait {

class Expression {
 public:
  // Compiles `text` over the variables named in `variables` (their order is evaluate()'s). Throws
  // ExpressionError naming the offending token and its character offset.
  Expression(const std::string& text, const std::vector<std::string>& variables);

  double evaluate(const double* values) const;

  // One instruction of the compiled (postfix) program.
  struct Op {
    enum Code { kConstant, kVariable, kAdd, kSubtract, kMultiply, kDivide, kPower, kNegate, kFunction1, kFunction2 };
    Code code;
    double value = 0;  // kConstant
    int index = 0;     // kVariable: the variable; kFunction1/2: the function
  };
 private:
  std::vector<Op> program_;  // postfix
  int depth_ = 0;            // stack depth the program needs
};

class ExpressionError : public std::runtime_error {
 public:
  ExpressionError(std::size_t offset, const std::string& message)
      : std::runtime_error("at character " + std::to_string(offset + 1) + ": " + message), offset(offset) {}
  std::size_t offset;
};

}  // namespace cpgait
