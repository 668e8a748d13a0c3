//! Writes the work-precision report of `docs/accuracy.md`: runs each sweep in
//! `examples/accuracy/`, prints a Markdown table per scene and writes its SVG plot to
//! `docs/accuracy/NAME.svg`.
//!
//! ```sh
//! cargo run --release --example work_precision > docs/accuracy/tables.md
//! ```

use std::path::Path;

use drape::sweep::{Sweep, Table, run_locally, write_svg};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let mut files: Vec<_> = std::fs::read_dir("examples/accuracy")?
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "json"))
        .collect();
    files.sort();
    for file in files {
        let name = file.file_stem().and_then(|s| s.to_str()).unwrap_or("sweep").to_string();
        let sweep = Sweep::from_json(&std::fs::read(&file)?, 1000)?;
        let table = run_locally(&sweep, threads);
        let plot = Path::new("docs/accuracy").join(format!("{name}.svg"));
        write_svg(&table, &name, std::fs::File::create(&plot)?)?;
        print_table(&name, &table);
    }
    Ok(())
}

fn print_table(name: &str, table: &Table) {
    println!("### {name}\n");
    if let Some(reference) = &table.reference {
        println!(
            "Reference: {} at dt = {:e} s ({:.2} s of wall time).\n",
            reference.integrator, reference.dt, reference.wall_time_s
        );
    }
    println!(
        "| integrator | dt (s) | status | wall time (s) | error vs reference (m) | own estimate (m) | estimate / error |"
    );
    println!("| --- | --- | --- | --- | --- | --- | --- |");
    for row in &table.rows {
        let error = row.reference_error.map(|(max, _)| max);
        let estimate = row.estimate.map(|(max, _)| max);
        let ratio = error.zip(estimate).filter(|(e, _)| *e > 0.0).map(|(e, s)| format!("{:.2}", s / e));
        let cell = |x: Option<f64>| x.map_or_else(|| "–".to_string(), |v| format!("{v:.2e}"));
        println!(
            "| {} | {:e} | {} | {:.2e} | {} | {} | {} |",
            row.integrator,
            row.dt,
            row.status,
            row.wall_time_s,
            cell(error),
            cell(estimate),
            ratio.unwrap_or_else(|| "–".into())
        );
    }
    let orders: Vec<String> = table
        .convergence()
        .iter()
        .map(|c| {
            format!(
                "{} {:.2}",
                c.group.iter().map(|(_, v)| v.as_str().unwrap_or("?")).collect::<Vec<_>>().join(" "),
                c.order
            )
        })
        .collect();
    if !orders.is_empty() {
        println!("\nObserved orders: {}.\n", orders.join(", "));
    }
    println!("![{name}](accuracy/{name}.svg)\n");
}
