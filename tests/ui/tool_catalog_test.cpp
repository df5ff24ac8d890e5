// The tools of the haptics panel (ui/tool_catalog.h) and the About box's text.
#include "vh/ui/tool_catalog.h"

#include <filesystem>

#include <gtest/gtest.h>

#include "ui_test_util.h"
#include "vh/datasets/synthetic.h"
#include "vh/runtime/placement.h"
#include "vh/runtime/scene.h"
#include "vh/ui/panels/about_dialog.h"

namespace vh::ui {
namespace {

namespace fs = std::filesystem;

TEST(ToolCatalog, BuiltInsAlwaysSharedMeshesWhenPresent) {
  const auto none = toolCatalog("/nonexistent");
  ASSERT_EQ(none.size(), 4u);
  EXPECT_EQ(none.front().id, "builtin:probe");
  const auto all = toolCatalog(test::kSharedData);
  if (fs::exists(test::kSharedData / "meshes/drill/drill.stl")) {
    const auto drill = std::find_if(all.begin(), all.end(), [](const ToolChoice& t) { return t.id == "mesh:drill"; });
    ASSERT_NE(drill, all.end());
    EXPECT_TRUE(fs::exists(drill->mesh));
    EXPECT_NEAR(drill->scale_to_m, 0.00044, 1e-12);
    EXPECT_FALSE(drill->credit.empty());
  }
}

TEST(ToolCatalog, SceneToolsMatchOrAreAdded) {
  auto catalog = toolCatalog("/nonexistent");
  runtime::ToolSpec spec;
  spec.mesh = "builtin:peg";
  EXPECT_EQ(catalog[static_cast<std::size_t>(findOrAddSceneTool(catalog, spec))].id, "builtin:peg");
  EXPECT_EQ(catalog.size(), 4u);
  spec.mesh = "/somewhere/custom.stl";
  spec.scale_to_m = 0.001;
  const int i = findOrAddSceneTool(catalog, spec);
  EXPECT_EQ(catalog.size(), 5u);
  EXPECT_EQ(catalog[static_cast<std::size_t>(i)].id, "scene");
  EXPECT_NE(catalog[static_cast<std::size_t>(i)].label.find("custom.stl"), std::string::npos);
}

TEST(ToolCatalog, BuildsAFreeToolAtTheAskedSpacing) {
  const haptics::ScalarVolume sphere = datasets::makeBuiltinVolume("sphere");
  const double iso = datasets::builtinIsovalue("sphere");
  const auto catalog = toolCatalog("/nonexistent");
  const BuiltTool t = buildTool(catalog[0], 0.002, sphere, iso);  // probe
  ASSERT_NE(t.tool, nullptr);
  EXPECT_DOUBLE_EQ(t.point_spacing_m, 0.002);
  EXPECT_GT(t.tool->point_shell.size(), 10u);
  EXPECT_EQ(runtime::countPointsInside(sphere, t.tool->point_shell, t.X_WT_initial, iso), 0);
  const BuiltTool automatic = buildTool(catalog[0], 0.0, sphere, iso);
  EXPECT_NEAR(automatic.point_spacing_m, runtime::automaticPointSpacing_m(automatic.tool->mesh_T, sphere), 1e-12);
  ToolChoice bad = catalog[0];
  bad.mesh = "/nonexistent/tool.stl";
  EXPECT_ANY_THROW(buildTool(bad, 0.002, sphere, iso));
}

TEST(About, NamesThePaperAndTheDataLicences) {
  const QString html = aboutHtml();
  EXPECT_TRUE(html.contains("Chan")) << html.toStdString();
  EXPECT_TRUE(html.contains("Salisbury"));
  EXPECT_TRUE(html.contains("WHC) 2011"));
  EXPECT_TRUE(html.contains("BSD-2-Clause")) << "the head phantom's licence from the manifest";
  EXPECT_TRUE(html.contains("CC-BY-4.0")) << "the wrench's licence";
  EXPECT_TRUE(aboutHtml("not json").contains("could not be read"));
  // Where the datasets are looked for and how to point the program at them.
  EXPECT_TRUE(html.contains("VH_SHARED_DATASETS_DIR")) << html.toStdString();
  EXPECT_TRUE(html.contains(QString::fromStdString(runtime::sharedDatasetsDir().string()).toHtmlEscaped()));
}

}  // namespace
}  // namespace vh::ui
