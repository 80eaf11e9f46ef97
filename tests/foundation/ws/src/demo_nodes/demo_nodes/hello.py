def run() -> None:
    print("hello", flush=True)
