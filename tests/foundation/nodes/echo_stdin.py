"""Test node: reads lines like the lab's goal publisher and echoes what it parsed."""
while True:
    try:
        data = input("Goal Position x,y: ")
    except EOFError:
        print("EOF", flush=True)
        break
    print(f"got {data!r}", flush=True)
