#include "host/report/html_report.hpp"

#include "host/io/output_file.hpp"

#include <stdexcept>

namespace btsm::report {

std::string html_escape(const std::string& s) {
  std::string out;
  out.reserve(s.size());
  for (char c : s) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      default: out += c;
    }
  }
  return out;
}

HtmlReport::HtmlReport(std::string title) : title_(std::move(title)) {}

void HtmlReport::heading(const std::string& t) { body_ += "<h2>" + html_escape(t) + "</h2>\n"; }
void HtmlReport::paragraph(const std::string& t) { body_ += "<p>" + html_escape(t) + "</p>\n"; }
void HtmlReport::preformatted(const std::string& t) { body_ += "<pre>" + html_escape(t) + "</pre>\n"; }

void HtmlReport::table(const std::vector<std::string>& header,
                       const std::vector<std::vector<std::string>>& rows) {
  body_ += "<table>\n<tr>";
  for (const auto& h : header) body_ += "<th>" + html_escape(h) + "</th>";
  body_ += "</tr>\n";
  for (const auto& r : rows) {
    body_ += "<tr>";
    for (const auto& c : r) body_ += "<td>" + html_escape(c) + "</td>";
    body_ += "</tr>\n";
  }
  body_ += "</table>\n";
}

void HtmlReport::image(const std::string& png, const std::string& caption) {
  body_ += "<figure><a href=\"" + html_escape(png) + "\"><img src=\"" + html_escape(png) +
           "\" alt=\"" + html_escape(caption) + "\"></a><figcaption>" + html_escape(caption) +
           "</figcaption></figure>\n";
}

std::string HtmlReport::html() const {
  return "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>" + html_escape(title_) +
         "</title>\n<style>body{font-family:sans-serif;max-width:1000px;margin:2em auto;color:#222}"
         "table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #bbb;padding:3px 8px;"
         "text-align:right}th{background:#eee}img{max-width:100%}figure{margin:1em 0}"
         "figcaption{color:#555;font-size:90%}pre{background:#f6f6f6;padding:8px;overflow:auto}</style>"
         "</head><body>\n<h1>" + html_escape(title_) + "</h1>\n" + body_ + "</body></html>\n";
}

void HtmlReport::write(const std::string& path) const { io::write_output_file(path, html(), "report page"); }

}  // namespace btsm::report
