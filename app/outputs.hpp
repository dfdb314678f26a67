#pragma once
// The run's files as one transaction (io::OutputSet) and the up-front size checks. Called by main.cpp
// and commands.cpp; see README "Output" and "Validation".
#include <functional>
#include <ostream>
#include <string>

#include "commands.hpp"
#include "lambert/io/atomic_file.hpp"
#include "lambert/mesh/soup.hpp"

namespace lambert::app {

// The outputs of this process's run.
io::OutputSet& outputs();

// Declares the run's inputs (scene, --materials) and outputs (-o, --stats) before any work: an output
// that is an input, another output, a directory, FIFO or device, or in a missing directory throws
// InputError now instead of after minutes of work.
void declare_files(const CommonOptions& o);

// Declares the files a reader read besides the scene (the OBJ's MTL libraries) as inputs.
void declare_soup_inputs(const mesh::PolygonSoup& soup);

// Writes a declared output to its temporary; commit_outputs() renames them all (or none).
void write_output(const std::string& path, const std::function<void(std::ostream&)>& fill);
void commit_outputs();

// Patches whose dense form-factor matrix (N^2 doubles) fits in 80% of physical memory.
long long max_patches_in_memory();
// The same for the operator --operator asks for: dense as above; hierarchical or auto: the patches whose
// estimated hierarchy fits in the memory available (formfactor::system_memory_limit).
long long max_patches_in_memory(const CommonOptions& o);

// --adaptive-budget N: refuses (InputError, with the estimate and the largest budget that fits) a budget
// whose final dense matrix cannot fit in memory, before any work starts.
void check_adaptive_budget(const CommonOptions& o);

}  // namespace lambert::app
