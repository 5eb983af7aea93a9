#include "cpgait/model/expression.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <map>

namespace cpgait {
namespace {

struct Function {
  const char* name;
  int arity;
  double (*f)(double, double);
};

// Lepton's functions (Operation.h), with its definitions of step and delta.
const Function kFunctions[] = {
    {"sqrt", 1, [](double x, double) { return std::sqrt(x); }},
    {"exp", 1, [](double x, double) { return std::exp(x); }},
    {"log", 1, [](double x, double) { return std::log(x); }},
    {"sin", 1, [](double x, double) { return std::sin(x); }},
    {"cos", 1, [](double x, double) { return std::cos(x); }},
    {"sec", 1, [](double x, double) { return 1.0 / std::cos(x); }},
    {"csc", 1, [](double x, double) { return 1.0 / std::sin(x); }},
    {"tan", 1, [](double x, double) { return std::tan(x); }},
    {"cot", 1, [](double x, double) { return 1.0 / std::tan(x); }},
    {"asin", 1, [](double x, double) { return std::asin(x); }},
    {"acos", 1, [](double x, double) { return std::acos(x); }},
    {"atan", 1, [](double x, double) { return std::atan(x); }},
    {"sinh", 1, [](double x, double) { return std::sinh(x); }},
    {"cosh", 1, [](double x, double) { return std::cosh(x); }},
    {"tanh", 1, [](double x, double) { return std::tanh(x); }},
    {"erf", 1, [](double x, double) { return std::erf(x); }},
    {"erfc", 1, [](double x, double) { return std::erfc(x); }},
    {"step", 1, [](double x, double) { return x >= 0.0 ? 1.0 : 0.0; }},
    {"delta", 1, [](double x, double) { return x == 0.0 ? 1.0 : 0.0; }},
    {"square", 1, [](double x, double) { return x * x; }},
    {"cube", 1, [](double x, double) { return x * x * x; }},
    {"recip", 1, [](double x, double) { return 1.0 / x; }},
    {"min", 2, [](double x, double y) { return std::min(x, y); }},
    {"max", 2, [](double x, double y) { return std::max(x, y); }},
    {"abs", 1, [](double x, double) { return std::abs(x); }},
};

struct Token {
  enum Type { kNumber, kOperator, kVariable, kFunction, kLeft, kRight, kComma } type;
  std::string text;  // a function's name without its '('
  std::size_t offset;
};

bool is_operator(char c) { return c == '+' || c == '-' || c == '*' || c == '/' || c == '^'; }

// Lepton's tokenizer: a name runs until an operator, comma, parenthesis or space; a name followed by
// '(' is a function.
std::vector<Token> tokenize(const std::string& s, std::size_t begin, std::size_t end) {
  std::vector<Token> out;
  for (std::size_t i = begin; i < end;) {
    const char c = s[i];
    if (std::isspace(static_cast<unsigned char>(c))) {
      ++i;
    } else if (c == '(' || c == ')' || c == ',') {
      out.push_back({c == '(' ? Token::kLeft : c == ')' ? Token::kRight : Token::kComma, std::string(1, c), i});
      ++i;
    } else if (is_operator(c)) {
      out.push_back({Token::kOperator, std::string(1, c), i});
      ++i;
    } else if (c == '.' || std::isdigit(static_cast<unsigned char>(c))) {
      std::size_t j = i + 1;
      bool decimal = c == '.', exponent = false;
      for (; j < end; ++j) {
        const char d = s[j];
        if (std::isdigit(static_cast<unsigned char>(d))) continue;
        if (d == '.' && !decimal) {
          decimal = true;
          continue;
        }
        if ((d == 'e' || d == 'E') && !exponent) {
          exponent = true;
          if (j + 1 < end && (s[j + 1] == '-' || s[j + 1] == '+')) ++j;
          continue;
        }
        break;
      }
      out.push_back({Token::kNumber, s.substr(i, j - i), i});
      i = j;
    } else {
      std::size_t j = i;
      while (j < end && s[j] != '(' && s[j] != ')' && s[j] != ',' && !is_operator(s[j]) && !std::isspace(static_cast<unsigned char>(s[j]))) ++j;
      if (j < end && s[j] == '(') {
        out.push_back({Token::kFunction, s.substr(i, j - i), i});
        i = j + 1;
      } else {
        out.push_back({Token::kVariable, s.substr(i, j - i), i});
        i = j;
      }
    }
  }
  return out;
}

// Lepton's precedence climbing (Parser::parsePrecedence): + - 0, * / 1, unary minus 2, ^ 3.
class ExpressionParser {
 public:
  ExpressionParser(const std::vector<std::string>& variables, const std::map<std::string, std::vector<Expression::Op>>& subexpressions)
      : variables_(variables), subexpressions_(subexpressions) {}

  std::vector<Expression::Op> parse(const std::vector<Token>& tokens, std::size_t end_offset) {
    tokens_ = &tokens;
    end_offset_ = end_offset;
    pos_ = 0;
    out_.clear();
    parse_precedence(0);
    if (pos_ != tokens.size()) throw ExpressionError(tokens[pos_].offset, "unexpected '" + tokens[pos_].text + "'");
    return out_;
  }

 private:
  const Token& peek() const {
    if (pos_ == tokens_->size()) throw ExpressionError(end_offset_, "unexpected end of expression");
    return (*tokens_)[pos_];
  }

  void parse_precedence(int precedence) {
    const Token t = peek();
    // Each level recurses; a bound keeps hostile input ("((((...") off the end of the stack.
    struct Depth {
      int& d;
      explicit Depth(int& d) : d(++d) {}
      ~Depth() { --d; }
    } depth(depth_);
    if (depth_ > 200) throw ExpressionError(t.offset, "nested more than 200 deep");
    using Op = Expression::Op;
    if (t.type == Token::kNumber) {
      char* stop = nullptr;
      const double v = std::strtod(t.text.c_str(), &stop);
      if (stop != t.text.c_str() + t.text.size()) throw ExpressionError(t.offset, "'" + t.text + "' is not a number");
      out_.push_back({Op::kConstant, v, 0});
      ++pos_;
    } else if (t.type == Token::kVariable) {
      const auto sub = subexpressions_.find(t.text);
      const auto var = std::find(variables_.begin(), variables_.end(), t.text);
      if (sub != subexpressions_.end()) {
        out_.insert(out_.end(), sub->second.begin(), sub->second.end());
      } else if (var != variables_.end()) {
        out_.push_back({Op::kVariable, 0, static_cast<int>(var - variables_.begin())});
      } else {
        std::string known;
        for (const auto& v : variables_) known += (known.empty() ? "" : ", ") + v;
        throw ExpressionError(t.offset, "unknown variable '" + t.text + "' (the expression may use " + known + ")");
      }
      ++pos_;
    } else if (t.type == Token::kLeft) {
      ++pos_;
      parse_precedence(0);
      if (pos_ == tokens_->size() || (*tokens_)[pos_].type != Token::kRight) throw ExpressionError(t.offset, "unbalanced parentheses");
      ++pos_;
    } else if (t.type == Token::kFunction) {
      const auto f = std::find_if(std::begin(kFunctions), std::end(kFunctions), [&](const Function& g) { return t.text == g.name; });
      if (f == std::end(kFunctions)) throw ExpressionError(t.offset, "unknown function '" + t.text + "'");
      ++pos_;
      int args = 0;
      for (bool more = true; more;) {
        parse_precedence(0);
        ++args;
        more = pos_ < tokens_->size() && (*tokens_)[pos_].type == Token::kComma;
        if (more) ++pos_;
      }
      if (pos_ == tokens_->size() || (*tokens_)[pos_].type != Token::kRight) throw ExpressionError(t.offset, "unbalanced parentheses");
      ++pos_;
      if (args != f->arity)
        throw ExpressionError(t.offset, "'" + t.text + "' takes " + std::to_string(f->arity) + " argument" + (f->arity == 1 ? "" : "s"));
      out_.push_back({f->arity == 1 ? Op::kFunction1 : Op::kFunction2, 0, static_cast<int>(f - std::begin(kFunctions))});
    } else if (t.type == Token::kOperator && t.text == "-") {
      ++pos_;
      parse_precedence(2);
      out_.push_back({Op::kNegate, 0, 0});
    } else {
      throw ExpressionError(t.offset, "unexpected '" + t.text + "'");
    }
    while (pos_ < tokens_->size() && (*tokens_)[pos_].type == Token::kOperator) {
      const char c = (*tokens_)[pos_].text[0];
      const int p = c == '+' || c == '-' ? 0 : c == '^' ? 3 : 1;
      if (p < precedence) return;
      ++pos_;
      parse_precedence(c == '^' ? p : p + 1);  // ^ is right-associative
      out_.push_back({c == '+' ? Op::kAdd : c == '-' ? Op::kSubtract : c == '*' ? Op::kMultiply : c == '/' ? Op::kDivide : Op::kPower, 0, 0});
    }
  }

  const std::vector<std::string>& variables_;
  const std::map<std::string, std::vector<Expression::Op>>& subexpressions_;
  const std::vector<Token>* tokens_ = nullptr;
  std::size_t end_offset_ = 0, pos_ = 0;
  int depth_ = 0;
  std::vector<Expression::Op> out_;
};

}  // namespace

Expression::Expression(const std::string& text, const std::vector<std::string>& variables) {
  // As Lepton: "primary; name=sub; ..." with the subexpressions parsed from the last, each seeing
  // those after it.
  std::vector<std::size_t> starts{0};
  for (std::size_t i = 0; i < text.size(); ++i)
    if (text[i] == ';') starts.push_back(i + 1);
  auto blank = [&](std::size_t b, std::size_t e) {
    return std::all_of(text.begin() + static_cast<std::ptrdiff_t>(b), text.begin() + static_cast<std::ptrdiff_t>(e),
                       [](char c) { return std::isspace(static_cast<unsigned char>(c)); });
  };
  std::map<std::string, std::vector<Op>> subexpressions;
  for (std::size_t k = starts.size() - 1; k >= 1; --k) {
    const std::size_t b = starts[k], e = k + 1 < starts.size() ? starts[k + 1] - 1 : text.size();
    if (blank(b, e)) continue;
    const std::size_t eq = text.find('=', b);
    std::string name = eq < e ? text.substr(b, eq - b) : "";
    name.erase(std::remove_if(name.begin(), name.end(), [](char c) { return std::isspace(static_cast<unsigned char>(c)); }), name.end());
    if (name.empty()) throw ExpressionError(b, "a subexpression after ';' needs a name: name=expression");
    subexpressions[name] = ExpressionParser(variables, subexpressions).parse(tokenize(text, eq + 1, e), e);
  }
  const std::size_t end = starts.size() > 1 ? starts[1] - 1 : text.size();
  const std::vector<Token> tokens = tokenize(text, 0, end);
  program_ = ExpressionParser(variables, subexpressions).parse(tokens, end);
  int d = 0;
  for (const Op& op : program_) {
    d += op.code == Op::kConstant || op.code == Op::kVariable ? 1 : op.code == Op::kNegate || op.code == Op::kFunction1 ? 0 : -1;
    depth_ = std::max(depth_, d);
  }
}

double Expression::evaluate(const double* values) const {
  double small[16] = {};
  std::vector<double> large;
  double* stack = small;
  if (depth_ > 16) {
    large.resize(static_cast<std::size_t>(depth_));
    stack = large.data();
  }
  int top = -1;
  for (const Op& op : program_) {
    switch (op.code) {
      case Op::kConstant: stack[++top] = op.value; break;
      case Op::kVariable: stack[++top] = values[op.index]; break;
      case Op::kAdd: stack[top - 1] += stack[top]; --top; break;
      case Op::kSubtract: stack[top - 1] -= stack[top]; --top; break;
      case Op::kMultiply: stack[top - 1] *= stack[top]; --top; break;
      case Op::kDivide: stack[top - 1] /= stack[top]; --top; break;
      case Op::kPower: stack[top - 1] = std::pow(stack[top - 1], stack[top]); --top; break;
      case Op::kNegate: stack[top] = -stack[top]; break;
      case Op::kFunction1: stack[top] = kFunctions[op.index].f(stack[top], 0.0); break;
      case Op::kFunction2: stack[top - 1] = kFunctions[op.index].f(stack[top - 1], stack[top]); --top; break;
    }
  }
  return stack[0];
}

}  // namespace cpgait
