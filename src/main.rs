fn main() -> std::process::ExitCode {
    avsep::cli::main()
}
