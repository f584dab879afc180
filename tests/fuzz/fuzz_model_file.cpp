// libFuzzer target: the model file (analyzer/model/model_file), as diagnose, simulate and online
// read it. A model that parses must format and parse back to the same model (the file's
// contract: read(write(m)) == m bit for bit). Bad input must be an InputError.
#include "analyzer/model/model_file.hpp"
#include "common/input_error.hpp"

using namespace inertia;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  model::ModelFile m;
  try {
    m = model::parse_model(text, "fuzz.toml");
  } catch (const InputError&) {
    return 0;
  }
  const std::string written = model::format_model(m);
  const model::ModelFile back = model::parse_model(written, "formatted.toml");
  if (back.terms.size() != m.terms.size() || back.m_cs != m.m_cs || back.white_sd != m.white_sd ||
      back.square_highpass_rad_s != m.square_highpass_rad_s || back.sensor != m.sensor)
    __builtin_trap();
  for (std::size_t i = 0; i < m.terms.size(); ++i)
    if (!(back.terms[i].term == m.terms[i].term) || back.terms[i].coefficient != m.terms[i].coefficient ||
        back.terms[i].std != m.terms[i].std)
      __builtin_trap();
  return 0;
}
