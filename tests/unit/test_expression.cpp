// Expressions in Lepton's grammar, as OpenSim's ExpressionBasedCoordinateForce writes them.
#include <gtest/gtest.h>
#include <cmath>

#include "cpgait/model/expression.h"

namespace cpgait {
namespace {

double eval(const std::string& text, double q, double qdot) {
  const double v[2] = {q, qdot};
  return Expression(text, {"q", "qdot"}).evaluate(v);
}

TEST(Expression, FollowsLeptonsPrecedenceAndAssociativity) {
  EXPECT_EQ(eval("-q^2", 3, 0), -9);            // ^ binds tighter than unary minus
  EXPECT_EQ(eval("2^3^2", 0, 0), 512);          // and is right-associative
  EXPECT_EQ(eval("-(q)*2", 3, 0), -6);
  EXPECT_EQ(eval("8/4/2", 0, 0), 1);            // / is left-associative
  EXPECT_EQ(eval("1-2-3", 0, 0), -4);
  EXPECT_EQ(eval("q*2-qdot/4", 1.5, 2), 2.5);
  EXPECT_DOUBLE_EQ(eval(" -10 * ( q - 0.5 ) - 0.1*qdot ", 1, 3), -5.3);
  EXPECT_DOUBLE_EQ(eval("1e-3*q+.5e+1", 2, 0), 5.002);
}

TEST(Expression, HasLeptonsFunctionsAndSubexpressions) {
  EXPECT_DOUBLE_EQ(eval("sqrt(q)+exp(0)+log(1)", 4, 0), 3);
  EXPECT_DOUBLE_EQ(eval("sec(q)*cos(q)+csc(q)*sin(q)", 0.3, 0), 2);
  EXPECT_DOUBLE_EQ(eval("cot(q)*tan(q)", 0.3, 0), 1);
  EXPECT_DOUBLE_EQ(eval("asin(sin(q))+acos(cos(q))+atan(tan(q))", 0.3, 0), 0.9);
  EXPECT_DOUBLE_EQ(eval("cosh(q)^2-sinh(q)^2", 0.7, 0), 1);
  EXPECT_DOUBLE_EQ(eval("tanh(q)", 0.7, 0), std::tanh(0.7));
  EXPECT_DOUBLE_EQ(eval("erf(q)+erfc(q)", 0.4, 0), 1);
  EXPECT_EQ(eval("step(q)", 0, 0), 1);  // Lepton: 1 at 0
  EXPECT_EQ(eval("step(q)", -1e-12, 0), 0);
  EXPECT_EQ(eval("delta(q)+delta(qdot)", 0, 1), 1);
  EXPECT_EQ(eval("square(q)+cube(q)+recip(q)", 2, 0), 12.5);
  EXPECT_EQ(eval("min(q,qdot)*max(q,qdot)+abs(-q)", -2, 5), -8);
  // Subexpressions, each seeing those defined after it.
  EXPECT_EQ(eval("k*(q-rest); k=a+1; a=2; rest=0.5", 1.5, 0), 3);
  EXPECT_EQ(eval("q;", 7, 0), 7);
}

TEST(Expression, ErrorsNameTheTokenAndItsPlace) {
  auto message = [](const std::string& text) {
    try {
      Expression(text, {"q", "qdot"});
    } catch (const ExpressionError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_EQ(message("q+"), "at character 3: unexpected end of expression");
  EXPECT_EQ(message("2*theta"), "at character 3: unknown variable 'theta' (the expression may use q, qdot)");
  EXPECT_EQ(message("foo(q)"), "at character 1: unknown function 'foo'");
  EXPECT_EQ(message("min(q)"), "at character 1: 'min' takes 2 arguments");
  EXPECT_EQ(message("(q"), "at character 1: unbalanced parentheses");
  EXPECT_EQ(message("q)"), "at character 2: unexpected ')'");
  EXPECT_EQ(message("+q"), "at character 1: unexpected '+'");
  EXPECT_EQ(message("q; 2"), "at character 3: a subexpression after ';' needs a name: name=expression");
  EXPECT_EQ(message(""), "at character 1: unexpected end of expression");
  EXPECT_EQ(message(std::string(100000, '(') + "q"), "at character 201: nested more than 200 deep");
  EXPECT_EQ(message(std::string(300, '-') + "q"), "at character 201: nested more than 200 deep");
  EXPECT_EQ(eval(std::string(150, '(') + "q" + std::string(150, ')'), 2, 0), 2);
}

}  // namespace
}  // namespace cpgait
