//! geomint in a Python process: the module `geomint_native`, which `geomint.local` calls with
//! the body the client would send to `POST /api/v1/simulate`. The request is read by the same
//! strict reader as the service's (`geomint-api`), run by the same core, and the document comes
//! back as the service's JSON (floats written so that they read back to the same bits), so the
//! client's own types read it and the numbers are the server's, bit for bit. The run computes
//! with the interpreter released (`Python::detach`), so other Python threads go on meanwhile.

use pyo3::prelude::*;

use geomint_api::simulate::simulate_to_json;
use geomint_api::ErrorDetail;
use geomint_core::simulation::Limits;

/// Runs the simulation `request` (JSON text, the body of `POST /api/v1/simulate`) and returns
/// `(True, document)` or `(False, error)`, both JSON text: the error is the service's
/// `{"code", "field", "position", "message"}` for a request it would refuse.
#[pyfunction]
fn simulate(py: Python<'_>, request: &str) -> (bool, String) {
    let request = request.to_owned();
    py.detach(move || match run(&request) {
        Ok(document) => (true, document),
        Err(error) => (false, to_json(&error)),
    })
}

/// The request read, checked against the service's default limits, and run with its methods
/// on as many threads as the machine has cores.
fn run(request: &str) -> Result<String, ErrorDetail> {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    simulate_to_json(request.as_bytes(), &Limits::default(), cores)
}

fn to_json(error: &ErrorDetail) -> String {
    serde_json::to_string(error).unwrap_or_else(|_| {
        r#"{"code": "internal", "message": "an error that could not be written"}"#.to_string()
    })
}

/// The module: `simulate`.
#[pymodule]
fn geomint_native(module: &Bound<'_, PyModule>) -> PyResult<()> {
    module.add_function(wrap_pyfunction!(simulate, module)?)
}
