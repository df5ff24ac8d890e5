// PNG charts with VTK's chart classes, rendered off screen (vtkContextView + vtkChartXY,
// vtkWindowToImageFilter, vtkPNGWriter). Needs an X display (Xvfb in tests).
#include <cmath>
#include <iostream>

#include <vtkAxis.h>
#include <vtkChartLegend.h>
#include <vtkChartXY.h>
#include <vtkContextScene.h>
#include <vtkContextView.h>
#include <vtkDoubleArray.h>
#include <vtkFloatArray.h>
#include <vtkNew.h>
#include <vtkPNGWriter.h>
#include <vtkPlot.h>
#include <vtkPlotBar.h>
#include <vtkRenderWindow.h>
#include <vtkRenderer.h>
#include <vtkStringArray.h>
#include <vtkTable.h>
#include <vtkTextProperty.h>
#include <vtkWindowToImageFilter.h>

#include "vh/bench/report.h"

namespace vh::bench {

namespace {

const unsigned char kColours[][3] = {{31, 119, 180}, {255, 127, 14}, {44, 160, 44}, {214, 39, 40},
                                     {148, 103, 189}, {140, 86, 75}, {227, 119, 194}, {127, 127, 127}};

bool render(vtkContextView* view, const std::filesystem::path& png, int width, int height) {
  view->GetRenderWindow()->SetOffScreenRendering(1);
  view->GetRenderWindow()->SetSize(width, height);
  view->GetRenderer()->SetBackground(1.0, 1.0, 1.0);
  view->GetRenderWindow()->Render();
  vtkNew<vtkWindowToImageFilter> grab;
  grab->SetInput(view->GetRenderWindow());
  grab->ReadFrontBufferOff();
  grab->Update();
  vtkNew<vtkPNGWriter> writer;
  writer->SetFileName(png.string().c_str());
  writer->SetInputConnection(grab->GetOutputPort());
  writer->Write();
  view->GetRenderWindow()->Finalize();
  std::error_code ec;
  if (!std::filesystem::exists(png, ec) || std::filesystem::file_size(png, ec) == 0) {
    std::cerr << "bench: " << png.string() << ": the PNG was not written\n";
    return false;
  }
  return true;
}

void styleChart(vtkChartXY* chart, const std::string& title, const std::string& x_label, const std::string& y_label) {
  chart->SetTitle(title);
  chart->GetTitleProperties()->SetFontSize(16);
  chart->GetAxis(vtkAxis::BOTTOM)->SetTitle(x_label);
  chart->GetAxis(vtkAxis::LEFT)->SetTitle(y_label);
  chart->SetShowLegend(true);
  chart->GetLegend()->SetHorizontalAlignment(vtkChartLegend::RIGHT);
  chart->GetLegend()->SetVerticalAlignment(vtkChartLegend::TOP);
}

/// False (with a message naming the plot) when there is no X display to render on.
bool canPlot(const std::filesystem::path& png) {
  if (displayAvailable()) return true;
  std::cerr << "bench: no X display (DISPLAY unset): plot " << png.filename().string()
            << " skipped (run under xvfb-run for plots)\n";
  return false;
}

}  // namespace

bool plotXY(const std::filesystem::path& png, const std::string& title, const std::string& x_label,
            const std::string& y_label, const std::vector<Series>& series, bool log_x, bool log_y, int width,
            int height) {
  if (!canPlot(png)) return false;
  vtkNew<vtkContextView> view;
  vtkNew<vtkChartXY> chart;
  view->GetScene()->AddItem(chart);
  styleChart(chart, title, x_label, y_label);
  int colour = 0;
  for (const Series& s : series) {
    if (s.x.empty() || s.x.size() != s.y.size()) continue;
    vtkNew<vtkTable> table;
    vtkNew<vtkDoubleArray> xs, ys;
    xs->SetName((s.name + " x").c_str());
    ys->SetName(s.name.c_str());
    table->AddColumn(xs);
    table->AddColumn(ys);
    table->SetNumberOfRows(static_cast<vtkIdType>(s.x.size()));
    for (std::size_t i = 0; i < s.x.size(); ++i) {
      // Log axes cannot show values <= 0: clamp them to a tiny positive value.
      const double x = log_x ? std::max(s.x[i], 1e-12) : s.x[i];
      const double y = log_y ? std::max(s.y[i], 1e-12) : s.y[i];
      table->SetValue(static_cast<vtkIdType>(i), 0, x);
      table->SetValue(static_cast<vtkIdType>(i), 1, y);
    }
    vtkPlot* plot = chart->AddPlot(s.points ? vtkChart::POINTS : vtkChart::LINE);
    plot->SetInputData(table, 0, 1);
    const unsigned char* c = kColours[colour++ % 8];
    plot->SetColor(c[0], c[1], c[2], 255);
    plot->SetWidth(s.points ? 4.0f : 1.5f);
    plot->SetLabel(s.name);
  }
  chart->GetAxis(vtkAxis::BOTTOM)->SetLogScale(log_x);
  chart->GetAxis(vtkAxis::LEFT)->SetLogScale(log_y);
  return render(view, png, width, height);
}

bool plotBars(const std::filesystem::path& png, const std::string& title, const std::vector<std::string>& categories,
              const std::string& y_label, const std::vector<Series>& series, bool log_y, int width, int height) {
  if (!canPlot(png)) return false;
  vtkNew<vtkContextView> view;
  vtkNew<vtkChartXY> chart;
  view->GetScene()->AddItem(chart);
  styleChart(chart, title, "", y_label);
  vtkNew<vtkTable> table;
  vtkNew<vtkDoubleArray> index;
  index->SetName("index");
  table->AddColumn(index);
  for (const Series& s : series) {
    vtkNew<vtkDoubleArray> col;
    col->SetName(s.name.c_str());
    table->AddColumn(col);
  }
  table->SetNumberOfRows(static_cast<vtkIdType>(categories.size()));
  for (std::size_t r = 0; r < categories.size(); ++r) {
    table->SetValue(static_cast<vtkIdType>(r), 0, static_cast<double>(r + 1));
    for (std::size_t c = 0; c < series.size(); ++c) {
      const double v = r < series[c].y.size() ? series[c].y[r] : 0.0;
      table->SetValue(static_cast<vtkIdType>(r), static_cast<vtkIdType>(c + 1), log_y ? std::max(v, 1e-3) : v);
    }
  }
  for (std::size_t c = 0; c < series.size(); ++c) {
    vtkPlot* plot = chart->AddPlot(vtkChart::BAR);
    plot->SetInputData(table, 0, static_cast<vtkIdType>(c + 1));
    const unsigned char* col = kColours[c % 8];
    plot->SetColor(col[0], col[1], col[2], 255);
    plot->SetLabel(series[c].name);
  }
  // Category names as tick labels.
  vtkNew<vtkDoubleArray> positions;
  vtkNew<vtkStringArray> labels;
  for (std::size_t r = 0; r < categories.size(); ++r) {
    positions->InsertNextValue(static_cast<double>(r + 1));
    labels->InsertNextValue(categories[r]);
  }
  vtkAxis* bottom = chart->GetAxis(vtkAxis::BOTTOM);
  bottom->SetCustomTickPositions(positions, labels);
  bottom->SetBehavior(vtkAxis::FIXED);
  bottom->SetRange(0.4, static_cast<double>(categories.size()) + 0.6);
  chart->GetAxis(vtkAxis::LEFT)->SetLogScale(log_y);
  return render(view, png, width, height);
}

}  // namespace vh::bench
