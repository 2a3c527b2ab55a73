#include "cad/sample_solids.h"

#include "cad/occt_lock.h"

#include <APIHeaderSection_MakeHeader.hxx>
#include <BRepAlgoAPI_Cut.hxx>
#include <BRepBuilderAPI_Transform.hxx>
#include <BRepPrimAPI_MakeBox.hxx>
#include <BRepPrimAPI_MakeCylinder.hxx>
#include <BRep_Builder.hxx>
#include <IGESControl_Controller.hxx>
#include <IGESControl_Writer.hxx>
#include <IGESData_GlobalSection.hxx>
#include <IGESData_IGESModel.hxx>
#include <Interface_Static.hxx>
#include <STEPControl_Writer.hxx>
#include <StepData_StepModel.hxx>
#include <TCollection_HAsciiString.hxx>
#include <TopoDS_Compound.hxx>
#include <gp_Ax2.hxx>
#include <gp_Trsf.hxx>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <mutex>
#include <regex>
#include <sstream>
#include <stdexcept>
#include <unistd.h>

namespace mm::cad {
namespace {

TopoDS_Shape drilled_block(double dx) {
  TopoDS_Shape block = BRepPrimAPI_MakeBox(gp_Pnt(dx, 0, 0), 40, 30, 20).Shape();
  const TopoDS_Shape bore = BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(dx + 14, 15, -1), gp_Dir(0, 0, 1)), 6, 22).Shape();
  const TopoDS_Shape side = BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(dx + 30, -1, 10), gp_Dir(0, 1, 0)), 3, 32).Shape();
  block = BRepAlgoAPI_Cut(block, bore).Shape();
  return BRepAlgoAPI_Cut(block, side).Shape();
}

TopoDS_Shape make(const std::string& name) {
  if (name == "drilled_block") return drilled_block(0);
  if (name == "block_pair") {
    TopoDS_Compound c;
    BRep_Builder b;
    b.MakeCompound(c);
    b.Add(c, drilled_block(0));
    b.Add(c, drilled_block(50));
    return c;
  }
  throw std::invalid_argument("unknown CAD sample \"" + name + "\"");
}

// A private temporary path for the writers that write files only; removed on destruction.
struct TempPath {
  std::string path;
  TempPath() {
    std::string pattern = (std::filesystem::temp_directory_path() / "meshmark-sample-XXXXXX").string();
    const int fd = ::mkstemp(pattern.data());
    if (fd < 0) throw std::runtime_error("cannot make a temporary file for a CAD sample");
    ::close(fd);
    path = pattern;
  }
  ~TempPath() { std::remove(path.c_str()); }
  std::string read() const {
    std::ifstream in(path, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  }
};

std::string step_bytes(const TopoDS_Shape& shape, const std::string& name) {
  STEPControl_Writer writer;
  Interface_Static::SetCVal("write.step.product.name", name.c_str());
  if (writer.Transfer(shape, STEPControl_AsIs) != IFSelect_RetDone)
    throw std::runtime_error("OpenCASCADE could not transfer the CAD sample to STEP");
  APIHeaderSection_MakeHeader header(writer.Model());
  header.SetName(new TCollection_HAsciiString(name.c_str()));
  header.SetTimeStamp(new TCollection_HAsciiString("2026-01-01T00:00:00"));
  header.Apply(writer.Model());
  const TempPath file;
  if (writer.Write(file.path.c_str()) != IFSelect_RetDone) throw std::runtime_error("OpenCASCADE could not write STEP");
  // OpenCASCADE numbers the product per transfer in the process ("drilled_block 2"): the number
  // is dropped, so every call writes the same bytes.
  return std::regex_replace(file.read(), std::regex("PRODUCT\\('" + name + " [0-9]+','" + name + " [0-9]+'"),
                            "PRODUCT('" + name + "','" + name + "'");
}

std::string iges_bytes(const TopoDS_Shape& shape) {
  IGESControl_Controller::Init();
  IGESControl_Writer writer("MM", 1);  // 1: B-rep solids
  writer.AddShape(shape);
  writer.ComputeModel();
  IGESData_GlobalSection global = writer.Model()->GlobalSection();
  global.SetDate(new TCollection_HAsciiString("20260101.000000"));
  global.SetLastChangeDate(new TCollection_HAsciiString("20260101.000000"));
  writer.Model()->SetGlobalSection(global);
  std::ostringstream out;
  if (!writer.Write(out)) throw std::runtime_error("OpenCASCADE could not write IGES");
  return out.str();
}

}  // namespace

const std::vector<std::string>& sample_solid_names() {
  static const std::vector<std::string> names{"drilled_block", "block_pair"};
  return names;
}

std::string sample_solid_bytes(const std::string& name, const std::string& format) {
  const bool step = format == "step" || format == "stp";
  if (!step && format != "iges" && format != "igs")
    throw std::invalid_argument("a CAD sample is written as step, stp, iges or igs, not \"" + format + "\"");
  const std::lock_guard<std::mutex> lock(occt_mutex());
  silence_occt();
  const TopoDS_Shape shape = make(name);
  return step ? step_bytes(shape, name) : iges_bytes(shape);
}

}  // namespace mm::cad
