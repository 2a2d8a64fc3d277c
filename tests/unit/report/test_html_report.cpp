#include "host/report/html_report.hpp"

#include <gtest/gtest.h>

using namespace btsm::report;

TEST(HtmlReport, EscapesTextAndBuildsTables) {
  HtmlReport r("Demo <1>");
  r.heading("Fit & validate");
  r.table({"node", "RMSE (K)"}, {{"T1", "0.005"}, {"<T2>", "0.006"}});
  r.image("fit.png", "measured vs predicted");
  const std::string h = r.html();
  EXPECT_NE(h.find("Demo &lt;1&gt;"), std::string::npos);
  EXPECT_NE(h.find("Fit &amp; validate"), std::string::npos);
  EXPECT_NE(h.find("<td>&lt;T2&gt;</td>"), std::string::npos);
  EXPECT_NE(h.find("<img src=\"fit.png\""), std::string::npos);
  EXPECT_EQ(h.find("<T2>"), std::string::npos);
}

TEST(HtmlReport, UnwritablePathThrows) {
  HtmlReport r("x");
  EXPECT_THROW(r.write("/nonexistent_dir/x/index.html"), std::runtime_error);
}
