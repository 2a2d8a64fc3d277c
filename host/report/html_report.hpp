#pragma once
// A self-contained HTML page (inline CSS, images referenced by relative path) built section by
// section: what the demo and `btsm residual --report` leave for people to open in a browser.
#include <string>
#include <vector>

namespace btsm::report {

class HtmlReport {
 public:
  explicit HtmlReport(std::string title);
  void heading(const std::string& text);                 // <h2>
  void paragraph(const std::string& text);               // escaped
  void preformatted(const std::string& text);            // <pre>, escaped
  void table(const std::vector<std::string>& header, const std::vector<std::vector<std::string>>& rows);
  void image(const std::string& relative_png, const std::string& caption);
  // Writes the page; throws std::runtime_error naming the path if it cannot.
  void write(const std::string& path) const;
  std::string html() const;

 private:
  std::string title_;
  std::string body_;
};

std::string html_escape(const std::string& s);

}  // namespace btsm::report
